"""``station robot ... --config FILE to-reference``: the arm's route to the station's reference pose from the
CLI, against the controller twin: through the lift pose, every step within the limit, nothing sent when
the route is refused."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import tomlkit

from sim.controller import ControllerTwin
from sim.station import sim_safety
from sim.world import REFERENCE_JOINTS_DEG, World
from station.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["robot", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def station_toml(path: Path, reference: tuple[float, ...], **safety: Any) -> Path:
    """The simulated cell's configuration: its reference pose and safety limits (``safety`` overrides)."""
    limits = {**sim_safety(World()), **safety}
    doc = {
        "name": "sim-cell",
        "robot": {"driver": "crs_a465", "reference_joints_deg": list(reference), "safety": limits},
        "camera": {"driver": "sim"},
    }
    path.write_text(tomlkit.dumps(doc), encoding="utf-8")
    return path


def test_to_reference_takes_the_sim_arm_from_its_ready_pose_through_the_lift_pose(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    config = station_toml(tmp_path / "station.toml", REFERENCE_JOINTS_DEG)
    code, out, err = run(capsys, "--sim", "--config", str(config), "--json", "to-reference")
    assert (code, err) == (0, "")
    done = json.loads(out)
    ready = [0.0, 0.0, 90.0, 0.0, 90.0, 0.0]  # where a fresh twin starts
    assert done["start"]["commanded_joints_deg"] == ready
    assert done["via_lift"] is True
    # up (forearm upright), then down to the reference; every step within 27 deg (30 less the margin)
    assert [0.0, 0.0, 0.0, 0.0, 90.0, 0.0] in done["moves"]
    previous = np.array(ready)
    for q in done["moves"]:
        assert np.max(np.abs(np.array(q) - previous)) <= 27.0 + 1e-9
        previous = np.array(q)
    assert done["moves"][-1] == list(REFERENCE_JOINTS_DEG)
    assert done["final_pose"]["commanded_joints_deg"] == list(REFERENCE_JOINTS_DEG)
    assert np.allclose(done["final_pose"]["joints_deg"], REFERENCE_JOINTS_DEG, atol=0.05)  # encoders
    assert done["at_reference"] is True


def test_to_reference_from_near_the_reference_is_one_move_and_from_there_none(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, make_twin: Callable[..., ControllerTwin]
) -> None:
    twin = make_twin(start_pose_deg=(5.0, 25.0, 70.0, -3.0, 90.0, 10.0))  # a small jog off the reference
    config = str(station_toml(tmp_path / "station.toml", REFERENCE_JOINTS_DEG))
    code, out, _ = run(capsys, "--port", twin.port, "--config", config, "--json", "to-reference")
    assert code == 0
    done = json.loads(out)
    assert (done["via_lift"], done["moves"]) == (False, [list(REFERENCE_JOINTS_DEG)])
    code, out, _ = run(capsys, "--port", twin.port, "--config", config, "to-reference")
    assert code == 0
    assert "route      none: already there" in out
    assert "commanded     +0.000    +30.000    +60.000" in out


def test_a_route_refused_by_the_cells_limits_moves_nothing(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, make_twin: Callable[..., ControllerTwin]
) -> None:
    # a cell whose ceiling the upright arm would break: the route through the lift pose is refused
    twin = make_twin()
    config = station_toml(tmp_path / "low.toml", REFERENCE_JOINTS_DEG, workspace_max_mm=(800, 800, 900))
    code, out, err = run(capsys, "--port", twin.port, "--config", str(config), "to-reference")
    assert (code, out) == (1, "")
    assert "the route to the reference pose is refused, nothing moved" in err
    assert "workspace box" in err
    assert not [line for line in twin.received if line.startswith("joint")]


def test_to_reference_needs_a_station_configuration(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, make_twin: Callable[..., ControllerTwin]
) -> None:
    twin = make_twin()
    code, out, err = run(capsys, "--port", twin.port, "to-reference")
    assert (code, out) == (2, "")
    assert err.startswith("station robot: to-reference needs --config FILE")
    code, _, err = run(capsys, "--port", twin.port, "--config", str(tmp_path / "none.toml"), "to-reference")
    assert code == 2
    assert "no such configuration file" in err
    assert twin.received == []  # nothing was opened or sent
