"""Conformance: the real driver against the controller twin over a real pseudo-terminal.

One contract suite, run against both motion modes of the twin (``mode``): the firmware's (the prompt
comes back at once while the arm moves on) and the older blocking one. Whatever the mode, a motion
method returns only once the arm has arrived.
"""

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
    NotHomedError,
    SafetyLimits,
    ServoError,
    ShellProfile,
)
from sim.controller import ControllerTwin
from station import config
from station.devices import DeviceBusyError, MotionRejectedError, MotionStoppedError, Robot, StopLatchedError
from station.kinematics import Kinematics, world_row
from tests.drivers.crs_a465.conftest import FAST_LINK, TWIN_MOTION
from tests.drivers.crs_a465.fakes import READY
from tests.local_ack import local_ack

AWAY = (5.0, -3.0, 85.0, 2.0, 88.0, -4.0)


def twin_in(make_twin, mode: str, **settings) -> ControllerTwin:
    return make_twin(motion_blocks=mode == "blocking", **settings)


def test_the_driver_is_a_robot_that_checks_a_move_without_sending_it(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    assert isinstance(robot, Robot)
    identity = robot.identity()
    assert identity.port == twin.port
    assert identity.model  # the arm type armstat reported at connect
    moves = len(twin.motion_log)
    with pytest.raises(MotionRejectedError, match=r"joint 1 at 400\.000 deg is outside its limits"):
        robot.check_move((400.0, 0.0, 90.0, 0.0, 90.0, 0.0))  # beyond J1's travel
    robot.check_move(AWAY)  # a legal move passes the check
    assert len(twin.motion_log) == moves  # checks moved nothing
    assert not any(line.startswith("joint") for line in twin.received)
    assert robot.where().commanded_joints_deg == READY


def test_connect_reads_the_twins_state(make_twin, robot_on, mode):
    robot = robot_on(twin_in(make_twin, mode, speed_pct=35))
    assert robot.last_status is not None
    assert robot.last_status.speed_pct == 35.0
    assert robot.last_position is not None
    assert robot.last_position.commanded_joints_deg == READY


def test_where_reports_the_twins_world_row_of_the_attained_joints(make_twin, robot_on, mode):
    robot = robot_on(twin_in(make_twin, mode))
    robot.move_joints(AWAY)
    p = robot.where()
    assert p.world_mm_deg is not None
    # the twin computes WORLD from the encoder angles; JOINTS are printed to 0.001 deg (~0.01 mm)
    assert_allclose(p.world_mm_deg, world_row(Kinematics().flange(p.joints_deg)), atol=0.01)


def test_move_joints_reaches_the_target_within_the_repeatability(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, repeat_sigma_deg=0.002)
    robot = robot_on(twin)
    robot.move_joints(AWAY)
    p = robot.where()
    assert p.commanded_joints_deg == AWAY
    assert_allclose(p.joints_deg, AWAY, atol=0.002 * 6)
    assert [m.kind for m in twin.motion_log] == [f"joint {i}" for i in range(1, 7)]


def test_repeated_returns_scatter_and_show_the_systematic_error(make_twin, robot_on, mode):
    twin = twin_in(
        make_twin, mode, repeat_sigma_deg=0.003, systematic_deg=(0.01, 0.0, 0.0, 0.0, 0.0, 0.0), seed=4
    )
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


def test_speed_home_and_ready(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    robot.set_speed(40)
    assert robot.status().speed_pct == 40.0
    robot.home()
    assert robot.where().commanded_joints_deg == (0.0,) * 6
    robot.ready()
    assert robot.where().commanded_joints_deg == READY
    assert [m.kind for m in twin.motion_log] == ["home", "ready"]


def test_arm_power_off_is_reported_by_the_controller(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    twin.set_power(False)
    with pytest.raises(ArmPowerOffError, match="joint: Arm power is OFF"):
        robot.move_joint(1, 1.0)
    assert robot.status().last_error == "joint: Arm power is OFF"


def test_not_homed_then_homed(make_twin, robot_on, mode):
    robot = robot_on(twin_in(make_twin, mode, homed=False))
    with pytest.raises(NotHomedError):
        robot.ready()
    robot.home()
    robot.ready()


def test_the_controllers_own_limit_error_comes_through(make_twin, robot_on, mode):
    narrow = ((-10.0, 10.0), (-90, 90), (-110, 110), (-180, 180), (-105, 105), (-180, 180))
    robot = robot_on(twin_in(make_twin, mode, joint_limits_deg=narrow))
    with pytest.raises(JointLimitError) as info:
        robot.move_joint(1, 15.0)
    assert info.value.axis == 1


def test_a_limp_axis_refuses_to_move(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    twin.arm.limp.add(4)
    with pytest.raises(AxisLimpError):
        robot.move_joint(4, 1.0)


def test_application_shell_reports_power_and_homing(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, shell="application", app_name="cal")
    robot = robot_on(twin)
    assert robot.shell == ShellProfile.application("cal")
    status = robot.status()
    assert (status.power, status.homed) == (True, True)
    twin.set_power(False)
    assert robot.status().power is False  # seen going off: an E-stop latches
    with pytest.raises(StopLatchedError, match="power went off"):
        robot.move_joint(2, 1.0)
    twin.set_power(True)
    robot.acknowledge_stop(local_ack())
    robot.move_joint(2, 1.0)


def test_a_motion_returns_only_once_the_arm_has_arrived(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, time_scale=20.0, repeat_sigma_deg=0.0, backlash_deg=0.0, settle_deg=0.0)
    robot = robot_on(twin)
    robot.move_joints((20.0, 0.0, 90.0, 0.0, 90.0, 0.0))
    assert not twin.arm.moving()
    assert robot.where().joints_deg == (20.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    robot.move_joint(2, -7.5)
    assert not twin.arm.moving()
    assert robot.last_arrival is not None
    assert robot.last_arrival.target_deg == (20.0, -7.5, 90.0, 0.0, 90.0, 0.0)
    robot.ready()
    assert not twin.arm.moving()
    assert robot.where().commanded_joints_deg == READY


def test_status_reports_motion_from_armstats_done_column(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, time_scale=1.0, speed_pct=5)
    robot = robot_on(twin)
    assert robot.status().moving is False
    twin.arm.move_joint(1, 20.0)  # moved by someone else (the pendant)
    assert robot.status().moving is True
    twin.arm.stop()
    assert robot.status().moving is False


def test_power_off_is_a_state_reported_by_status(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    twin.set_power(False)
    status = robot.status()
    assert (status.power, status.homed, status.calibrated, status.arm_type) == (False, True, True, "A465")
    assert robot.identity().model == "A465"


def _move_in_thread(robot: CrsA465, axis: int, delta: float) -> tuple[threading.Thread, list[BaseException]]:
    outcome: list[BaseException] = []

    def move() -> None:
        try:
            robot.move_joint(axis, delta)
        except BaseException as exc:  # noqa: BLE001 - handed to the test thread
            outcome.append(exc)

    mover = threading.Thread(target=move)
    mover.start()
    return mover, outcome


def _wait_moving(twin: ControllerTwin) -> None:
    """Until the arm is on its way (joint 1 past 1 deg), so that a stop lands mid-motion."""
    for _ in range(1000):
        if twin.arm.moving() and twin.arm.commanded()[0] > 1.0:
            return
        threading.Event().wait(0.01)


def test_stop_halts_a_motion_in_progress_and_latches(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, time_scale=1.0, speed_pct=5)  # 30 deg at 9 deg/s: several seconds
    robot = robot_on(twin)
    mover, outcome = _move_in_thread(robot, 1, 30.0)
    _wait_moving(twin)
    robot.stop()
    mover.join(timeout=20)
    assert not mover.is_alive()
    assert len(outcome) == 1
    assert isinstance(outcome[0], MotionStoppedError)
    assert "acknowledge" in str(outcome[0])
    assert twin.motion_log[-1].stopped
    assert not twin.arm.moving()
    reached = robot.where().commanded_joints_deg[0]
    assert 0.0 < reached < 30.0
    assert all(not any(ord(c) < 0x20 for c in line) for line in twin.received)  # no stray control byte
    with pytest.raises(MotionStoppedError, match="acknowledge"):
        robot.move_joint(1, 1.0)
    robot.connect()  # connecting again does not release the latch
    with pytest.raises(MotionStoppedError):
        robot.move_joint(1, 1.0)
    with pytest.raises(MotionStoppedError, match="not cleared by starting again"):
        robot.clear_stop()  # what a session's start calls
    assert robot.acknowledge_stop(local_ack()) is not None  # a person at the station
    robot.move_joint(1, 1.0)


def test_a_stop_between_two_motions_is_not_lost(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot = robot_on(twin)
    robot.move_joint(1, 1.0)
    robot.stop()
    with pytest.raises(MotionStoppedError):
        robot.move_joint(1, 1.0)
    assert [m.kind for m in twin.motion_log] == ["joint 1"]


def test_a_servo_error_during_the_motion_is_raised(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode, time_scale=1.0)  # 20 deg in about 0.35 s: the fault fires half-way
    robot = robot_on(twin)
    twin.inject("servo@2:Excessive lag error on axis 1")  # w0, then the joint move
    with pytest.raises(ServoError, match="Excessive lag error on axis 1"):
        robot.move_joint(1, 20.0)
    assert twin.motion_log[-1].stopped


def test_the_port_is_opened_exclusively(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
    robot_on(twin)
    second = CrsA465(twin.port, link=FAST_LINK, motion=TWIN_MOTION)
    with pytest.raises(DeviceBusyError, match="in use"):
        second.connect()


def test_reconnecting_rereads_what_another_client_changed(make_twin, robot_on, mode):
    twin = twin_in(make_twin, mode)
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
        robot = config.build(
            "robot",
            "crs_a465",
            port=twin.port,
            link=FAST_LINK,
            safety={"max_step_deg": 10},
            motion=TWIN_MOTION,
        )
        assert isinstance(robot, CrsA465)
        assert not robot.is_connected  # the factory does not connect
        try:
            robot.connect()
            assert robot.guard.limits.max_step_deg == 10
            robot.move_joint(6, 3.0)
            assert robot.where().commanded_joints_deg[5] == 3.0
        finally:
            robot.close()
    finally:
        twin.close()
