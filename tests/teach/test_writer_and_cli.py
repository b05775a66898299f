"""The configuration writer (comments kept, the old file backed up, an invalid result refused) and
``station teach`` on the simulated station."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sim.world import REFERENCE_JOINTS_DEG
from station.cli import main
from station.config import ConfigurationError, load_config
from station.kinds.calibration.plan import LOOK_DOWN as PLAN_LOOK_DOWN
from station.kinds.calibration.plan import square_on as plan_square_on
from station.teach import LOOK_DOWN, fit_plane, set_artifact, set_reference, square_on, update_config

CONFIG = """\
# the lab's station: keep this comment
name = "lab"

[robot]
driver = "crs_a465"
options = { port = "/dev/ttyS0" }   # the console port
reference_joints_deg = [0, 30, 60, 0, 90, 0]

[camera]
driver = "sim"

[calibration]
artifacts_mm = [[482, 0, 329]]
working_distance_mm = 68   # the lens's
pixel_mm = 0.01
"""


def test_taught_values_are_written_with_the_comments_kept_and_the_old_file_backed_up(tmp_path: Path):
    path = tmp_path / "station.toml"
    path.write_text(CONFIG, encoding="utf-8")
    done = update_config(path, lambda doc: set_reference(doc, (0.0011, 29.99, 60.0144, 0, 90, 0)))
    text = path.read_text(encoding="utf-8")
    assert "# the lab's station: keep this comment" in text
    assert "# the console port" in text
    assert done.backup.read_text(encoding="utf-8") == CONFIG
    assert done.config.robot is not None
    assert done.config.robot.reference_joints_deg == (0.001, 29.99, 60.014, 0.0, 90.0, 0.0)
    again = update_config(
        path, lambda doc: set_artifact(doc, "block A", (350.41, 250.2, 381.6), (0.171, -0.296, 0.94), 150.1)
    )
    assert again.backup != done.backup  # no backup is overwritten
    cal = load_config(path).calibration
    assert cal is not None
    assert cal.names() == ["1", "block A"]
    assert cal.artifacts_mm[1] == (350.41, 250.2, 381.6)
    assert cal.artifact_turns_deg == [0.0, 150.1]
    assert "# the lens's" in path.read_text(encoding="utf-8")


def test_an_edit_that_makes_the_configuration_invalid_writes_nothing(tmp_path: Path):
    path = tmp_path / "station.toml"
    path.write_text(CONFIG, encoding="utf-8")
    with pytest.raises(ConfigurationError, match="artifact_normals"):
        update_config(path, lambda doc: set_artifact(doc, "1", (1, 2, 3), (1.0, 0.0, 0.0), 0.0))  # not upward
    assert path.read_text(encoding="utf-8") == CONFIG
    assert list(tmp_path.iterdir()) == [path]


def test_the_turn_convention_is_the_calibration_plans():
    for n in ((0, 0, 1), (0.171, -0.296, 0.94), (-0.366, 0.211, 0.906)):
        np.testing.assert_allclose(square_on(n), plan_square_on(n), atol=1e-15)
    np.testing.assert_array_equal(LOOK_DOWN, PLAN_LOOK_DOWN)
    plane = fit_plane(np.array([[0, 0, 1], [1, 0, 1.5], [0, 1, 1], [1, 1, 1.5]], dtype=float))
    np.testing.assert_allclose(plane.normal, np.array([-0.5, 0, 1]) / np.hypot(0.5, 1), atol=1e-12)


def test_station_teach_reference_on_the_sim_writes_the_configuration(tmp_path: Path, capsys):
    path = tmp_path / "station.toml"
    path.write_text(CONFIG.replace("[0, 30, 60, 0, 90, 0]", "[0, 31, 60, 0, 90, 0]"), encoding="utf-8")
    assert main(["teach", "reference", "--sim", "--config", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    taught = out["taught"]["reference_joints_deg"]
    np.testing.assert_allclose(taught, REFERENCE_JOINTS_DEG, atol=0.05)
    robot = load_config(path).robot
    assert robot is not None
    assert list(robot.reference_joints_deg) == taught
    assert Path(out["backup"]).exists()
    with pytest.raises(SystemExit) as usage:
        main(["teach", "artifact", "--config", str(path)])  # NAME missing
    assert usage.value.code == 2
