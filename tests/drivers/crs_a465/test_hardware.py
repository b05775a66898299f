"""On a real C500C with its A465 and the station's camera (``pytest --hardware``), the checks DIALECT.md's
assumptions ask of a real controller. ``$STATION_CONFIG`` names the station configuration (its [robot]
port, safety limits and keep-out, [camera], [calibration] working distance); the arm must be powered,
homed, and at the reference pose over the table's crossing, in focus (``station robot --config F
to-reference``), the cell watched with a hand on the E-stop. The halt test leaves the stop latched on
purpose: acknowledge it afterwards at the station (``station robot --config F acknowledge``).
"""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

from drivers.crs_a465 import CrsA465
from station import config
from station.devices import Camera, RobotStatus
from station.selftest import SelftestRig, check_halt, run_selftest, selftest_rig

pytestmark = [pytest.mark.hardware, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def devices() -> Iterator[tuple[CrsA465, Camera, config.StationConfig]]:
    path = os.environ.get("STATION_CONFIG")
    if not path:
        pytest.skip("set STATION_CONFIG to the station configuration (its [robot] port, safety and [camera])")
    station = config.load_config(path)
    opened = config.open_station(station)
    robot = opened.robot
    if not isinstance(robot, CrsA465):
        pytest.skip(f"STATION_CONFIG's [robot] is not a crs_a465 (it is {station.robot})")
    robot.connect()
    opened.camera.connect()
    try:
        yield robot, opened.camera, station
    finally:
        opened.camera.close()
        robot.close()
        opened.close_owned()


def _rig(robot: CrsA465, camera: Camera, station: config.StationConfig) -> SelftestRig:
    limits = robot.guard.limits
    return selftest_rig(
        station, robot, camera, ready_pose_deg=limits.ready_pose_deg, max_step_deg=limits.max_step_deg
    )


def test_the_controller_reports_power_homing_and_a_world_row(
    devices: tuple[CrsA465, Camera, config.StationConfig],
) -> None:
    robot, _, _ = devices
    status = robot.status()
    assert isinstance(status, RobotStatus)
    assert status.power is True, "switch the arm power on (armstat reports it off)"
    assert status.homed is True, "home the arm (station robot --config F home)"
    assert status.speed_pct is not None
    assert status.speed_pct <= robot.guard.limits.max_speed_pct
    where = robot.where()
    assert where.world_mm_deg is not None, "w2 printed no WORLD row: DIALECT.md's table format differs"
    assert max(abs(a - c) for a, c in zip(where.joints_deg, where.commanded_joints_deg, strict=True)) < 0.5


def test_directions_world_and_ready_agree_with_the_station_s_models(
    devices: tuple[CrsA465, Camera, config.StationConfig],
) -> None:
    result = run_selftest(_rig(*devices), checks=("directions", "world", "ready"))
    assert result.passed, "\n".join(f"{c.name}: {c.state}: {c.summary}" for c in result.checks)


def test_the_halt_key_stops_a_slow_move(devices: tuple[CrsA465, Camera, config.StationConfig]) -> None:
    check = check_halt(_rig(*devices))
    assert check.state == "passed", f"{check.summary} ({check.details})"
