"""Pre-flight: every problem of a session's steps found at once, before anything moves; and the session's
first motion, the arm's route to the plan's reference pose.

``find_problems`` is the one list of pre-flight checks: a new check is one more line there.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import BaseModel

from station.arm_route import TO_REFERENCE_HINT, describe_offset, max_step_of, plan_route
from station.config import StationDevices
from station.devices import DeviceError, MotionRejectedError, Robot, StopLatchedError, XYTable
from station.plans import MoveAligned, MoveJoints, MoveOffset, MoveTable, Plan, PlanContext, SetSpeed, Step
from station.record import Record
from station.runner._states import PRELUDE_BASE

MAX_LISTED = 20
"""Pre-flight lists at most this many problems (and says how many more)."""


def find_problems(
    steps: Sequence[Step], devices: StationDevices | None, found: Sequence[str] = ()
) -> list[str]:
    """Every problem of running ``steps`` on ``devices`` (``found``: those found before, e.g. the route's),
    at most ``MAX_LISTED`` of them; an empty list when the session may start."""
    problems = list(found)
    if devices is not None and devices.robot is not None:
        problems += robot_problems(steps, devices.robot)
    if devices is not None and devices.table is not None:
        problems += table_problems(steps, devices.table)
    if len(problems) > MAX_LISTED:
        problems = [*problems[:MAX_LISTED], f"... and {len(problems) - MAX_LISTED} more"]
    return problems


def robot_problems(steps: Sequence[Step], robot: Robot) -> list[str]:
    """The arm: its stop latch, power and homing, every motion's target and every speed (the driver's
    checks), when the steps use the arm."""
    if not any(isinstance(a, MoveJoints | SetSpeed) for s in steps for a in s.actions):
        return []
    problems: list[str] = []
    try:
        robot.clear_stop()  # releases nothing: a latched stop is a problem, acknowledged locally
    except StopLatchedError as exc:
        problems.append(str(exc))
    try:
        status = robot.status()
        if status.power is False:
            problems.append("the arm's power is off: switch it on at the controller, then start again")
        if status.homed is False:
            problems.append("the arm is not homed: home it (station robot ... home), then start again")
        start = tuple(robot.where().commanded_joints_deg)
    except DeviceError as exc:
        return [*problems, f"the robot cannot be read: {exc}"]
    return problems + _motion_problems(steps, robot, start) + _speed_problems(steps, robot)


def _motion_problems(steps: Sequence[Step], robot: Robot, start: tuple[float, ...]) -> list[str]:
    problems: list[str] = []
    previous: Sequence[float] = start
    seen: set[tuple[tuple[float, ...], tuple[float, ...]]] = set()
    for step in steps:
        base: Sequence[float] = previous  # where a MoveOffset's offsets start (planned)
        for action in step.actions:
            if isinstance(action, MoveOffset):
                target = tuple(b + o for b, o in zip(base, action.offset_deg, strict=True))
                try:
                    robot.check_move(target, start_deg=previous)
                except MotionRejectedError as exc:
                    problems.append(f"{step.name}: {exc}")
                previous = target
                continue
            if not isinstance(action, MoveJoints | MoveAligned):
                continue
            # a re-centred move is checked at its planned pose (no correction); the runner checks it
            # again where it goes
            target = action.target_deg if isinstance(action, MoveJoints) else action.planned_deg
            base = target
            key = (tuple(previous), target)
            if key not in seen:
                seen.add(key)
                try:
                    robot.check_move(target, start_deg=previous)
                except MotionRejectedError as exc:
                    problems.append(f"{step.name}: {exc}")
            previous = target
    return problems


def _speed_problems(steps: Sequence[Step], robot: Robot) -> list[str]:
    """Every speed the plan sets, against the station's cap (the driver's check)."""
    problems: list[str] = []
    speeds: set[float] = set()
    for step in steps:
        for action in step.actions:
            if isinstance(action, SetSpeed) and action.percent not in speeds:
                speeds.add(action.percent)
                try:
                    robot.check_speed(action.percent)
                except MotionRejectedError as exc:
                    problems.append(f"{step.name}: {exc}")
    return problems


def table_problems(steps: Sequence[Step], table: XYTable) -> list[str]:
    """Every table target against the table's travel."""
    problems: list[str] = []
    checked: set[tuple[float, float]] = set()
    for step in steps:
        for action in step.actions:
            if isinstance(action, MoveTable) and (action.x_mm, action.y_mm) not in checked:
                checked.add((action.x_mm, action.y_mm))
                try:
                    table.check_target(action.x_mm, action.y_mm)
                except MotionRejectedError as exc:
                    problems.append(f"{step.name}: {exc}")
    return problems


def route_to_reference(
    plan: Plan,
    params: BaseModel,
    ctx: PlanContext,
    devices: StationDevices | None,
    record: Record,
    prelude: Sequence[Step],
) -> tuple[list[Step], list[str]]:
    """The session's first motion: the arm's route to the plan's reference pose from where it is
    commanded (``station.arm_route``), as a step; none when the arm is there. For a plan that never
    moves the arm, the pre-flight problem when it is not there instead."""
    robot = devices.robot if devices is not None else None
    pose = plan.reference_pose(params, ctx)
    if devices is None or robot is None or pose is None:
        return [], []
    try:
        start = tuple(robot.where().commanded_joints_deg)
    except DeviceError as exc:  # pre-flight says so too when the plan moves the arm
        why = f"the robot cannot be read (a {plan.name} needs the arm at its reference pose): {exc}"
        return [], [] if pose.route else [why]
    safety = devices.config.robot.safety if devices.config.robot is not None else None
    route = plan_route(start, pose.joints_deg, max_step_deg=max_step_of(safety))
    if not route.moves:
        return [], []
    if not pose.route:
        return [], [
            f"the arm is not at its reference pose ({describe_offset(start, route.target_deg)}); a"
            f" {plan.name} never moves the arm: {TO_REFERENCE_HINT}, then start again"
        ]
    assert ctx.session_id is not None
    used = [s.index for s in record.steps(ctx.session_id)] + [s.index for s in prelude]
    index = max([PRELUDE_BASE - 1, *used]) + 1
    how = "through the lift pose" if route.via_lift else "direct"
    meta = {"role": "route", "via_lift": route.via_lift, "start_deg": list(start)}
    step = Step(index, f"to the reference pose ({how})", tuple(MoveJoints(q) for q in route.moves), meta)
    # not one of the plan's steps: progress counts those (as it does not count a resume's prelude)
    return [step], []
