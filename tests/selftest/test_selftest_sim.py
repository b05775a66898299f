"""The controller self-test on the simulated station (issue 23, item 3): a sound controller passes, and
each check fails on the fault it is for (a camera mounted otherwise than configured, a controller whose
joint zero differs from the station's arm model, a halt key the controller ignores)."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np
import pytest

from drivers.crs_a465 import CrsA465, ShellProfile, build_robot
from sim.station import build_sim_station
from station.config import StationDevices
from station.devices import StopLatchedError
from station.kinematics import A465_DH, Kinematics, rot_z, transform
from station.selftest import (
    HALT_MOVE_DEG,
    STOP_ANGLE_DEG,
    SelftestRig,
    check_halt,
    run_selftest,
    selftest_rig,
)
from tests.local_ack import local_ack

pytestmark = pytest.mark.timeout(240)


def _rig(devices: StationDevices, robot: CrsA465) -> SelftestRig:
    limits = robot.guard.limits
    return selftest_rig(
        devices.config,
        robot,
        devices.camera,
        ready_pose_deg=limits.ready_pose_deg,
        max_step_deg=limits.max_step_deg,
    )


@pytest.fixture(scope="module")
def station() -> Iterator[tuple[StationDevices, SelftestRig]]:
    devices = build_sim_station(seed=5)
    assert isinstance(devices.robot, CrsA465)
    devices.robot.connect()
    devices.camera.connect()
    try:
        yield devices, _rig(devices, devices.robot)
    finally:
        devices.robot.close()
        devices.camera.close()
        devices.close_owned()


def test_a_sound_controller_passes_and_the_arm_ends_where_it_began(
    station: tuple[StationDevices, SelftestRig],
) -> None:
    _devices, rig = station
    start = rig.commanded()
    result = run_selftest(rig, checks=("directions", "world", "ready"))
    assert [c.name for c in result.checks] == ["directions", "world", "ready"]
    assert result.passed, [c.summary for c in result.checks]
    assert not result.latched
    world = result.check("world").details
    assert len(world["poses"]) == 5
    assert world["worst_mm"] < 0.05  # the twin's WORLD is the nominal flange; printed to 3 decimals
    directions = result.check("directions").details["joints"]
    assert [j["joint"] for j in directions] == [1, 2, 3, 4, 5, 6]
    cosines = sorted(j["cosine"] for j in directions)
    assert cosines[0] > 0.85
    assert cosines[3] > 0.99
    np.testing.assert_allclose(rig.commanded(), start, atol=1e-3)
    assert result.to_dict()["identity"]["model"] == "A465"


def test_a_camera_mounted_otherwise_than_configured_fails_the_directions(
    station: tuple[StationDevices, SelftestRig],
) -> None:
    _, rig = station
    upside_down = rig.nominal.with_tool(rig.nominal.tool @ transform(rot_z(np.pi), (0.0, 0.0, 0.0)))
    result = run_selftest(dataclasses.replace(rig, nominal=upside_down), checks=("directions",))
    check = result.check("directions")
    assert check.state == "failed"
    assert "[camera] mount" in check.summary or "mounting" in check.summary
    failing = {j["joint"] for j in check.details["joints"] if not j["passed"]}
    assert {1, 3, 4, 5} <= failing  # their view shifts point the other way
    assert all(j["cosine"] < -0.9 for j in check.details["joints"] if j["joint"] in (1, 4, 5))


def test_a_joint_zero_other_than_the_arm_model_s_fails_world(
    station: tuple[StationDevices, SelftestRig],
) -> None:
    _, rig = station
    dh = list(A465_DH)
    dh[1] = dataclasses.replace(dh[1], theta_offset_deg=dh[1].theta_offset_deg + 0.2)
    result = run_selftest(dataclasses.replace(rig, arm_model=Kinematics(dh)), checks=("world",))
    check = result.check("world")
    assert check.state == "failed"
    assert check.details["worst_mm"] > 0.5
    assert "joint zeros" in check.summary


def test_the_halt_key_stops_a_slow_move_within_the_stated_angle_and_latches() -> None:
    devices = build_sim_station(seed=6, time_scale=1.0)  # real time: the halt is timed
    robot = devices.robot
    assert isinstance(robot, CrsA465)
    robot.connect()
    devices.camera.connect()
    try:
        start = robot.where().commanded_joints_deg
        check = check_halt(_rig(devices, robot))
        assert check.state == "passed", check.summary
        travelled = check.details["travelled_deg"]
        assert 0.5 < travelled < HALT_MOVE_DEG - 0.5  # halted on the way
        assert check.details["stopping_angle_deg"] <= STOP_ANGLE_DEG
        with pytest.raises(StopLatchedError):
            robot.move_joints(start)
        assert robot.acknowledge_stop(local_ack()) is not None
        robot.move_joints(start)
    finally:
        robot.close()
        devices.camera.close()
        devices.close_owned()


def test_a_halt_key_the_controller_ignores_fails_the_halt() -> None:
    devices = build_sim_station(seed=7, time_scale=1.0)
    assert devices.config.robot is not None
    robot = build_robot(
        devices.config.robot.options["port"],
        shell=ShellProfile.system(stop_sequence="\x03"),  # Ctrl-C: the shell ignores SIGINT [F]
        safety=devices.config.robot_safety(),
    )
    robot.connect()
    devices.camera.connect()
    try:
        check = check_halt(_rig(devices, robot))
        assert check.state == "failed", check.summary
        assert "did not stop" in check.summary
        assert check.details["travelled_deg"] == pytest.approx(HALT_MOVE_DEG, abs=0.05)
    finally:
        robot.close()
        devices.camera.close()
        devices.close_owned()


def test_a_ready_pose_other_than_the_configured_one_fails_ready() -> None:
    devices = build_sim_station(seed=8, ready_pose_deg=(0.0, 0.0, 90.0, 0.0, 80.0, 0.0))  # the controller's
    robot = devices.robot
    assert isinstance(robot, CrsA465)
    robot.connect()
    devices.camera.connect()
    try:
        start = robot.where().commanded_joints_deg
        check = run_selftest(_rig(devices, robot), checks=("ready",)).check("ready")
        assert check.state == "failed"
        assert "ready_pose_deg" in check.summary
        assert check.details["worst_deg"] == pytest.approx(10.0)
        np.testing.assert_allclose(robot.where().commanded_joints_deg, start, atol=1e-3)  # and back
    finally:
        robot.close()
        devices.camera.close()
        devices.close_owned()


def test_the_rig_takes_the_ready_pose_and_step_from_the_configuration_as_the_driver_does(
    station: tuple[StationDevices, SelftestRig],
) -> None:
    devices, _ = station
    robot = devices.robot
    assert isinstance(robot, CrsA465)
    rig = selftest_rig(
        devices.config, robot, devices.camera
    )  # what the session code, without the driver, calls
    assert rig.ready_pose_deg == robot.guard.limits.ready_pose_deg
    assert rig.max_step_deg == robot.guard.limits.max_step_deg
