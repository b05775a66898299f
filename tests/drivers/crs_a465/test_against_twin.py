"""Conformance: the real driver against the controller twin over a real pseudo-terminal."""

from __future__ import annotations

import threading

import numpy as np
import pytest
from numpy.testing import assert_allclose

from drivers.crs_a465 import (
    ArmPowerOffError,
    AxisLimpError,
    CrsA465,
    JointLimitError,
    LinkSettings,
    NotHomedError,
    SafetyLimits,
    ShellProfile,
)
from station import config
from station.devices import MotionStoppedError, Robot
from station.kinematics import Kinematics, world_row
from tests.drivers.crs_a465.conftest import FAST_LINK
from tests.drivers.crs_a465.fakes import READY

AWAY = (5.0, -3.0, 85.0, 2.0, 88.0, -4.0)


def test_the_driver_is_a_robot(make_twin, robot_on):
    assert isinstance(robot_on(make_twin()), Robot)


def test_connect_reads_the_twins_state(make_twin, robot_on):
    robot = robot_on(make_twin(speed_pct=35))
    assert robot.last_status is not None
    assert robot.last_status.speed_pct == 35.0
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg == READY


def test_where_reports_the_twins_world_row_of_the_attained_joints(make_twin, robot_on):
    robot = robot_on(make_twin())
    robot.move_joints(AWAY)
    p = robot.where()
    assert p.world_mm_deg is not None
    # the twin computes WORLD from the encoder angles; JOINTS are printed to 0.001 deg (~0.01 mm)
    assert_allclose(p.world_mm_deg, world_row(Kinematics().flange(p.joints_deg)), atol=0.01)


def test_move_joints_reaches_the_target_within_the_repeatability(make_twin, robot_on):
    twin = make_twin(repeat_sigma_deg=0.002)
    robot = robot_on(twin)
    robot.move_joints(AWAY)
    p = robot.where()
    assert p.commanded_joints_deg == AWAY
    assert_allclose(p.joints_deg, AWAY, atol=0.002 * 6)
    assert [m.kind for m in twin.motion_log] == [f"joint {i}" for i in range(1, 7)]


def test_repeated_returns_scatter_and_show_the_systematic_error(make_twin, robot_on):
    twin = make_twin(repeat_sigma_deg=0.003, systematic_deg=(0.01, 0.0, 0.0, 0.0, 0.0, 0.0), seed=4)
    robot = robot_on(twin, safety=SafetyLimits(max_step_deg=10.0))
    attained = []
    for _ in range(12):
        robot.move_joint(1, 5.0)
        robot.move_joint(1, -5.0)
        attained.append(robot.where().joints_deg)
    a = np.asarray(attained)
    assert a[:, 0].std() > 0.001  # the random part is there to be found
    assert a[:, 0].mean() == pytest.approx(0.01, abs=0.004)  # and the systematic part
    assert_allclose(a[:, 1:], np.tile(READY[1:], (12, 1)))  # joints that never moved keep their place


def test_speed_home_and_ready(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    robot.set_speed(80)
    assert robot.status().speed_pct == 80.0
    robot.home()
    assert robot.where().commanded_joints_deg == (0.0,) * 6
    robot.ready()
    assert robot.where().commanded_joints_deg == READY
    assert [m.kind for m in twin.motion_log] == ["home", "ready"]


def test_arm_power_off_is_reported_by_the_controller(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.set_power(False)
    with pytest.raises(ArmPowerOffError, match="007 Arm power is OFF"):
        robot.move_joint(1, 1.0)
    assert robot.status().last_error == "joint: 007 Arm power is OFF"


def test_not_homed_then_homed(make_twin, robot_on):
    robot = robot_on(make_twin(homed=False))
    with pytest.raises(NotHomedError):
        robot.ready()
    robot.home()
    robot.ready()


def test_the_controllers_own_limit_error_comes_through(make_twin, robot_on):
    narrow = ((-10.0, 10.0), (-90, 90), (-110, 110), (-180, 180), (-105, 105), (-180, 180))
    robot = robot_on(make_twin(joint_limits_deg=narrow))
    with pytest.raises(JointLimitError) as info:
        robot.move_joint(1, 15.0)
    assert info.value.axis == 1


def test_a_limp_axis_refuses_to_move(make_twin, robot_on):
    twin = make_twin()
    robot = robot_on(twin)
    twin.arm.limp.add(4)
    with pytest.raises(AxisLimpError):
        robot.move_joint(4, 1.0)


def test_application_shell_reports_power_and_homing(make_twin, robot_on):
    twin = make_twin(shell="application", app_name="cal")
    robot = robot_on(twin)
    assert robot.shell == ShellProfile.application("cal")
    status = robot.status()
    assert (status.power, status.homed) == (True, True)
    twin.set_power(False)
    assert robot.status().power is False
    with pytest.raises(ArmPowerOffError):
        robot.move_joint(2, 1.0)


def test_non_blocking_motion_waits_until_settled(make_twin, robot_on):
    twin = make_twin(
        motion_blocks=False, time_scale=20.0, repeat_sigma_deg=0.0, backlash_deg=0.0, settle_deg=0.0
    )
    robot = robot_on(twin, shell=ShellProfile.system(motion_blocks=False))
    robot.move_joints((20.0, 0.0, 90.0, 0.0, 90.0, 0.0))
    robot.wait_settled(timeout_s=10.0)
    assert not twin.arm.moving()
    assert robot.where().joints_deg == (20.0, 0.0, 90.0, 0.0, 90.0, 0.0)


def test_stop_interrupts_a_motion_in_progress(make_twin, robot_on):
    twin = make_twin(time_scale=1.0, speed_pct=5)  # 30 deg at 9 deg/s: several seconds
    robot = robot_on(twin, link=LinkSettings(motion_timeout_s=30.0, resync_quiet_s=0.02))
    outcome: list[BaseException] = []

    def move() -> None:
        try:
            robot.move_joint(1, 30.0)
        except BaseException as exc:  # noqa: BLE001 - handed to the test thread
            outcome.append(exc)

    mover = threading.Thread(target=move)
    mover.start()
    for _ in range(500):
        if twin.arm.moving():
            break
        threading.Event().wait(0.01)
    robot.stop()
    mover.join(timeout=10)
    assert not mover.is_alive()
    assert len(outcome) == 1
    assert isinstance(outcome[0], MotionStoppedError)
    assert twin.motion_log[-1].stopped
    reached = robot.where().commanded_joints_deg[0]
    assert 0.0 < reached < 30.0


def test_reconnecting_rereads_what_another_client_changed(make_twin, robot_on):
    twin = make_twin()
    first = robot_on(twin)
    first.close()
    second = robot_on(twin)
    second.move_joint(1, 7.0)
    second.set_speed(20)
    second.close()
    first.connect()
    assert first.last_position is not None
    assert first.last_position.commanded_joints_deg[0] == 7.0
    assert first.last_status is not None
    assert first.last_status.speed_pct == 20.0


def test_robot_and_twin_are_built_through_the_device_registry():
    twin = config.build("controller", "sim", time_scale=100.0, seed=2)
    try:
        robot = config.build("robot", "crs_a465", port=twin.port, link=FAST_LINK, safety={"max_step_deg": 10})
        assert isinstance(robot, CrsA465)
        try:
            assert robot.guard.limits.max_step_deg == 10
            robot.move_joint(6, 3.0)
            assert robot.where().commanded_joints_deg[5] == 3.0
        finally:
            robot.close()
    finally:
        twin.close()
