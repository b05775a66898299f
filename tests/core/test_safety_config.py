"""The cell's safety in the station configuration (issue 23): keep-out volumes, the camera's mounting
(translation and rotation, one model for the keep-out and the calibration), the speed cap."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drivers.crs_a465 import SafetyLimits
from station.config import ConfigurationError, load_config
from station.mounts import CameraMount, camera_mount_of
from station.speed_cap import SpeedCapError, check_plan_speeds, check_speed, speed_cap_of

STATION = """
name = "lab"

[robot]
driver = "crs_a465"
options = {{ port = "/dev/ttyS0" }}
reference_joints_deg = [0, 30, 60, 0, 90, 0]
{safety}

[[robot.safety.keep_out]]
shape = "box"
name = "X-Y table"          # the carriage and its micrometers
center_mm = [482, 0, 290]
size_mm = [220, 220, 70]

[[robot.safety.keep_out]]
shape = "cylinder"
name = "angle block 1"
base_mm = [350, 250, 250]
radius_mm = 40
height_mm = 95

[camera]
driver = "sim"
{mount}

[distance_sensor]
driver = "keyence_il"
options = {{ port = "/dev/ttyUSB0" }}
mount = {{ translation_mm = [30, 0, 0], body = {{ radius_mm = 20, z_from_mm = -70, z_to_mm = -10 }} }}
"""


def write(tmp_path: Path, *, safety: str = "", mount: str = "") -> Path:
    path = tmp_path / "station.toml"
    path.write_text(STATION.format(safety=safety or "[robot.safety]\nmax_speed_pct = 40", mount=mount))
    return path


def test_keepout_volumes_and_a_turned_camera_reach_the_drivers_limits(tmp_path: Path):
    config = load_config(
        write(
            tmp_path,
            mount="mount = { translation_mm = [0, 10, 120], rotation_deg = [0, 0, 90], front_mm = 5 }",
        )
    )
    mount = config.camera_mount()
    np.testing.assert_allclose(mount.matrix()[:3, 0], [0, 1, 0], atol=1e-12)  # the image's x along flange y
    limits = SafetyLimits(**config.robot_safety())
    assert [v.name for v in limits.keep_out] == ["X-Y table", "angle block 1"]
    assert limits.max_speed_pct == 40
    np.testing.assert_allclose(limits.camera_offset_mm, [0, 10, 125])  # the lens front, 5 mm ahead
    bodies = {b.name: b for b in limits.carried}
    np.testing.assert_allclose(bodies["camera body"].end_mm, [0, 10, 125])
    # the sensor head: 30 mm along the camera's x, which the 90 deg turn lays along the flange's y
    np.testing.assert_allclose(bodies["distance sensor head"].start_mm, [0, 40, 50], atol=1e-9)
    np.testing.assert_allclose(bodies["distance sensor head"].end_mm, [0, 40, 110], atol=1e-9)


def test_an_old_translation_only_offset_still_loads_as_a_mount_without_rotation(tmp_path: Path):
    old = "[robot.safety]\ncamera_offset_mm = [0, 0, 120]\nmin_camera_height_mm = 40"
    config = load_config(write(tmp_path, safety=old))
    assert config.camera_mount() == CameraMount(translation_mm=(0.0, 0.0, 120.0))
    np.testing.assert_allclose(config.camera_mount().matrix()[:3, :3], np.eye(3))
    assert SafetyLimits(**config.robot_safety()).max_speed_pct == 50  # the default cap
    assert camera_mount_of(config.model_dump(mode="json")) == config.camera_mount()


def test_a_camera_described_twice_differently_is_refused(tmp_path: Path):
    both = write(
        tmp_path,
        safety="[robot.safety]\ncamera_offset_mm = [0, 0, 100]",
        mount="mount = { translation_mm = [0, 0, 120] }",
    )
    with pytest.raises(ConfigurationError, match="describe the camera once"):
        load_config(both)


def test_the_speed_cap_and_the_plan_check_for_pre_flight():
    assert speed_cap_of({}) == 50.0
    assert speed_cap_of({"max_speed_pct": 30}) == 30.0
    problems = check_plan_speeds({"speed_pct": 80}, speed_cap_of({}))  # repeatability's default
    assert len(problems) == 1
    assert "the plan's speed_pct 80 % refused: the station's speed cap is 50 %" in problems[0]
    assert "max_speed_pct in [robot] safety" in problems[0]
    assert check_plan_speeds({"speed_pct": 50, "align_speed_pct": 20}, 50.0) == []
    with pytest.raises(SpeedCapError):
        check_speed(float("nan"), 50.0)
    with pytest.raises(ValueError, match="max_speed_pct"):
        speed_cap_of({"max_speed_pct": 150})
