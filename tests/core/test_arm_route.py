"""The arm's route to a pose (``station.arm_route``): direct within one step, else up, across and down
through the lift poses; every step within the limit; checked move by move before the first is sent."""

from __future__ import annotations

import numpy as np
import pytest

from station.arm_route import (
    RouteRejectedError,
    go_to_reference,
    lift_pose,
    plan_route,
    quantised,
    robot_status,
)
from station.testing import FakeRobot

REF = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)
OVER_A_BENCH_ARTIFACT = (36.87, 71.123, 14.456, -160.094, 46.5, 12.3)


def steps_of(start: tuple[float, ...], moves: tuple[tuple[float, ...], ...]) -> list[float]:
    path = np.array([start, *moves])
    return [float(v) for v in np.max(np.abs(np.diff(path, axis=0)), axis=1)]


@pytest.mark.parametrize("max_step", [30.0, 20.0, 7.5])
def test_a_far_route_goes_up_across_and_down_in_steps_within_the_limit(max_step: float) -> None:
    route = plan_route(OVER_A_BENCH_ARTIFACT, REF, max_step_deg=max_step)
    assert route.via_lift
    assert max(steps_of(route.start_deg, route.moves)) <= 0.9 * max_step + 1e-9
    assert lift_pose(OVER_A_BENCH_ARTIFACT) in route.moves  # up first, the wrist as it was
    assert lift_pose(REF) in route.moves  # across with the arm upright
    up, across = route.moves.index(lift_pose(OVER_A_BENCH_ARTIFACT)), route.moves.index(lift_pose(REF))
    assert up < across
    assert all(q[1] == 0.0 and q[2] == 0.0 for q in route.moves[up : across + 1])  # upright all across
    assert route.moves[-1] == REF
    assert all(q == quantised(q) for q in route.moves)  # at the controller's 0.001 deg
    assert len(set(route.moves)) == len(route.moves)  # no move to where the arm already is


def test_within_one_step_the_route_is_one_move_and_at_the_pose_none() -> None:
    near = (5.0, 25.0, 70.0, -3.0, 90.0, 10.0)
    route = plan_route(near, REF, max_step_deg=30.0)
    assert (route.moves, route.via_lift) == ((REF,), False)
    assert plan_route((0.0, 30.004, 59.998, 0.0, 90.0, 0.0), REF, max_step_deg=30.0).moves == ()
    # from the ready pose two joints differ by 30 deg, more than one route step (27): up and down
    assert plan_route((0.0, 0.0, 90.0, 0.0, 90.0, 0.0), REF, max_step_deg=30.0).via_lift


def test_an_upright_start_skips_the_leg_that_does_not_move() -> None:
    route = plan_route(lift_pose(REF), REF, max_step_deg=30.0)
    assert route.via_lift
    assert route.moves == ((0.0, 10.0, 20.0, 0.0, 90.0, 0.0), (0.0, 20.0, 40.0, 0.0, 90.0, 0.0), REF)


@pytest.mark.parametrize(
    ("start", "target", "step", "message"),
    [
        ((0.0,) * 5, REF, 30.0, "start_deg must be 6 finite joint angles"),
        (REF, (0.0, float("nan"), 0.0, 0.0, 0.0, 0.0), 30.0, "target_deg must be 6 finite"),
        (REF, REF, 0.0, "max_step_deg must be a positive number"),
    ],
)
def test_bad_input_is_refused_naming_it(
    start: tuple[float, ...], target: tuple[float, ...], step: float, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        plan_route(start, target, max_step_deg=step)


def test_go_to_reference_sends_every_move_and_reports_them() -> None:
    robot = FakeRobot(OVER_A_BENCH_ARTIFACT)
    robot.connect()
    done = go_to_reference(robot, REF, max_step_deg=30.0)
    sent = [c[0] for c in robot.calls_of("move_joints")]
    assert [tuple(q) for q in done.moves] == sent
    assert done.start.commanded_joints_deg == list(OVER_A_BENCH_ARTIFACT)
    assert done.final_pose.commanded_joints_deg == list(REF)
    assert done.at_reference
    assert done.via_lift


def test_a_route_the_robot_refuses_anywhere_moves_nothing() -> None:
    # joint 3 may not reach 0: the lift pose is out of this arm's limits
    robot = FakeRobot(
        OVER_A_BENCH_ARTIFACT, limits_deg=[(-175, 175), (-90, 110), (10, 110), *[(-180, 180)] * 3]
    )
    robot.connect()
    status = robot_status(robot, REF, 30.0)
    assert not status.at_reference
    assert status.route.problems[0].startswith("move 1 of 12 to (36.870, 47.415, 9.637,")
    assert status.route.problems[0].endswith("joint 3 target 9.637 deg is outside 10 to 110")
    with pytest.raises(RouteRejectedError) as info:
        go_to_reference(robot, REF, max_step_deg=30.0)
    assert info.value.problems == status.route.problems
    assert "nothing moved" in str(info.value)
    robot.assert_not_called("move_joints")
