"""Host-side checks: no motion outside the limits, the step or the keep-out ever reaches the port."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.crs_a465 import MotionGuard, SafetyLimits
from station.devices import MotionRejectedError
from station.kinematics import Kinematics
from tests.drivers.crs_a465.fakes import READY, connect_exchanges, scripted_robot, w0

MOTION_WORDS = ("joint", "ready", "home", "move", "motor")

# A table plane 380 mm above the base: the ready pose's camera (459 mm) is 79 mm above it.
HIGH_TABLE = SafetyLimits(table_z_mm=380.0, min_camera_height_mm=50.0, max_step_deg=45.0)


def camera_heights(limits: SafetyLimits, path: np.ndarray) -> np.ndarray:
    """Independent of the guard: camera point heights above the table along a joint path."""
    kin = Kinematics()
    point = np.array([*limits.camera_offset_mm, 1.0])
    return np.array([(kin.flange(q) @ point)[2] - limits.table_z_mm for q in path])


def test_accepts_a_small_move_from_ready():
    plan = MotionGuard(HIGH_TABLE).plan_single_joint_moves(READY, [(1, 10.0), (5, -5.0)])
    assert plan.steps == ((1, 10.0), (5, -5.0))
    assert plan.end_deg == (10.0, 0.0, 90.0, 0.0, 85.0, 0.0)


def test_rejects_a_target_outside_the_joint_limits():
    with pytest.raises(
        MotionRejectedError, match=r"joint 2 at 95\.000 deg is outside its limits \[-90, 90\]"
    ):
        MotionGuard().check_limits((0, 95, 0, 0, 0, 0))


def test_station_limits_narrow_the_arms_limits():
    guard = MotionGuard(SafetyLimits(joint_limits_deg=((-10, 10), (-200, 200), *[(-100, 100)] * 4)))
    assert guard.joint_limits[0].tolist() == [-10, 10]
    assert guard.joint_limits[1].tolist() == [-90, 90]  # never wider than the arm
    with pytest.raises(MotionRejectedError, match="joint 1"):
        guard.check_limits((11, 0, 90, 0, 90, 0))


def test_rejects_a_step_larger_than_the_maximum():
    guard = MotionGuard(SafetyLimits(max_step_deg=5.0))
    with pytest.raises(MotionRejectedError, match="maximum step of 5 deg"):
        guard.plan_single_joint_moves(READY, [(3, -5.5)])


def test_rejects_a_camera_below_the_clearance():
    with pytest.raises(MotionRejectedError, match="camera would come to"):
        MotionGuard(HIGH_TABLE).plan_single_joint_moves(READY, [(3, 10.0)])


def test_rejects_a_flange_outside_the_workspace_box():
    limits = SafetyLimits(workspace_max_mm=(800.0, 800.0, 1000.0))
    with pytest.raises(MotionRejectedError, match="workspace box"):
        MotionGuard(limits).check_linear(READY, (0, 0, 0, 0, 0, 0), step=False)


def test_a_dip_between_the_ends_is_caught_and_another_axis_order_chosen():
    # Joint 2 forward first would tilt the camera down into the table; joint 3 first keeps it up.
    start, steps = READY, [(2, 20.0), (3, -20.0)]
    guard = MotionGuard(HIGH_TABLE)
    natural = np.array([start, (0, 20, 90, 0, 90, 0), (0, 20, 70, 0, 90, 0)], dtype=float)
    assert guard.path_violation(list(natural)) is not None  # the waypoints, row by row
    assert camera_heights(HIGH_TABLE, natural)[-1] > 50.0  # both ends are fine
    plan = guard.plan_single_joint_moves(start, steps)
    assert plan.steps == ((3, -20.0), (2, 20.0))


def test_rejects_when_no_axis_order_is_safe():
    with pytest.raises(MotionRejectedError, match="no order"):
        MotionGuard(HIGH_TABLE).plan_single_joint_moves(READY, [(2, 20.0), (3, 10.0)])


def test_sampling_catches_a_dip_inside_one_joint_move():
    # Joint 5 from 75 to 105 with the forearm horizontal swings the camera through straight down
    # (at 90): both ends are 65 mm above the table, the middle 59 mm.
    limits = SafetyLimits(table_z_mm=400.0, min_camera_height_mm=62.0)
    start, end = (0, 0, 90, 0, 75, 0), (0, 0, 90, 0, 105, 0)
    assert camera_heights(limits, np.array([start, end])).min() > 62.0
    with pytest.raises(MotionRejectedError, match="camera"):
        MotionGuard(limits).plan_single_joint_moves(start, [(5, 30.0)])


def test_limits_and_keepout_settings_are_validated():
    with pytest.raises(ValueError, match="joint_limits_deg"):
        SafetyLimits(joint_limits_deg=((1, -1),) * 6)
    with pytest.raises(ValueError, match="workspace"):
        SafetyLimits(workspace_min_mm=(0, 0, 0), workspace_max_mm=(0, 10, 10))


# ------------------------------------------------------------------ nothing leaves the host


def test_a_limit_failure_writes_nothing_at_all():
    with scripted_robot(connect_exchanges()) as (robot, port):
        robot.connect()
        sent = len(port.written)
        with pytest.raises(MotionRejectedError):
            robot.move_joints((0, 0, 90, 0, 90, 181))
        with pytest.raises(MotionRejectedError):
            robot.move_joint(7, 1.0)
        assert len(port.written) == sent


def test_a_step_or_keepout_failure_writes_only_the_position_query():
    with scripted_robot([*connect_exchanges(), w0(), w0(), w0()], safety=HIGH_TABLE) as (robot, port):
        robot.connect()
        sent = len(port.written)
        with pytest.raises(MotionRejectedError, match="maximum step"):
            robot.move_joints((0, 0, 40, 0, 90, 0))
        with pytest.raises(MotionRejectedError, match="camera"):
            robot.move_joint(3, 10.0)
        with pytest.raises(MotionRejectedError, match="camera"):
            robot.move_joints((0, 0, 100, 0, 90, 0))
        assert bytes(port.written[sent:]) == b"w0\r" * 3


def test_ready_is_checked_against_the_keepout():
    limits = SafetyLimits(table_z_mm=420.0)  # the ready pose's camera would be 39 mm above the table
    with scripted_robot([*connect_exchanges(), w0()], safety=limits) as (robot, port):
        robot.connect()
        with pytest.raises(MotionRejectedError, match="camera"):
            robot.ready()
        assert not port.written.endswith(b"ready\r")


def test_random_moves_against_the_twin_never_send_an_unsafe_motion(make_twin, robot_on):
    """Fuzz: every rejected move leaves the twin without a motion; every executed one stays clear."""
    twin = make_twin(repeat_sigma_deg=0.0)
    robot = robot_on(twin, safety=HIGH_TABLE)
    rng = np.random.default_rng(5)
    rejected = accepted = 0
    for _ in range(40):
        start = np.asarray(robot.where().commanded_joints_deg)
        target = start + rng.uniform(-30.0, 30.0, 6) * rng.integers(0, 2, 6)
        moves_before = len(twin.motion_log)
        received_before = len(twin.received)
        try:
            robot.move_joints(target)
        except MotionRejectedError:
            rejected += 1
            assert len(twin.motion_log) == moves_before
            new_lines = twin.received[received_before:]
            assert not [line for line in new_lines if line.split()[0] in MOTION_WORDS], new_lines
            continue
        accepted += 1
        for move in twin.motion_log[moves_before:]:
            path = np.linspace(move.start_deg, move.end_deg, 50)
            assert camera_heights(HIGH_TABLE, path).min() >= 50.0 - 1e-6, move
            assert Kinematics().within_limits(move.end_deg)
    assert rejected >= 5
    assert accepted >= 5
