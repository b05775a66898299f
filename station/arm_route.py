"""The way to a pose: the arm's route from wherever it is, every move checked before the first is sent.

A route from ``start`` to ``target`` (six joint angles, deg) is a list of joint waypoints at the
controller's resolution (0.001 deg), consecutive ones within the driver's largest joint step less 10 %
(room for that rounding):

* **direct** when every joint is within one such step of the target (a small excursion: a repeatability
  cycle left unfinished, a nudge with the pendant): a single move;
* otherwise **through the lift poses**, up, across and down, as the calibration plan travels between
  artifacts: the upper arm and forearm raised upright with the other joints where they are, then the
  base and the wrist turned with the arm upright, then down to the target. On the way the camera stays
  high above every artifact of the cell, which the driver's keep-out (the table plane) knows nothing of.

Sessions take this route to their reference pose as their first motion (``station/runner.py``), and
``station robot ... to-reference`` and ``POST /api/v1/station/robot/to-reference`` run it alone
(:func:`go_to_reference`): every move is checked with the robot's own ``check_move`` (limits, step,
keep-out) from the arm's actual commanded position before the first one is sent, so a route refused
anywhere moves nothing.

Only the device interfaces (``station/devices/``) and the pure joint-space maths are used here: the
drivers' CLI, the runner and the station worker all call it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field

from station.devices import JOINT_COUNT, MotionRejectedError, Robot, RobotPosition

JOINT_DECIMALS = 3
"""The C500C's joint resolution in its commands and position reports (0.001 deg)."""

DEFAULT_MAX_STEP_DEG = 30.0
"""The largest joint change per call when the robot's safety settings do not say (the CRS driver's)."""

STEP_MARGIN = 0.9
"""Route steps use this fraction of the largest joint step: waypoints rounded to 0.001 deg stay within it."""

AT_POSE_TOLERANCE_DEG = 0.01
"""The arm is at a pose when every commanded joint is within this of it (ten controller counts)."""

TO_REFERENCE_HINT = (
    "bring it there with `station robot --port PORT --config FILE to-reference` or the operator page's"
    " To reference button (POST /api/v1/station/robot/to-reference)"
)
"""What to do when the arm is not at its reference pose (error messages end with it)."""


def quantised(q: npt.ArrayLike) -> tuple[float, ...]:
    """Joint angles rounded to the controller's resolution (0.001 deg): what it can be commanded to, so
    that a sequence of relative moves lands exactly on the target."""
    return tuple(round(float(a), JOINT_DECIMALS) for a in np.asarray(q, dtype=float))


def unwrap_near(q: npt.ArrayLike, seed: npt.ArrayLike, limits: npt.ArrayLike) -> tuple[float, ...]:
    """``q`` with each joint moved by whole turns to the equivalent angle nearest ``seed`` that stays within
    its limits (inverse kinematics wraps angles to (-180, 180]: joint 6 at +180 and -180 is one pose)."""
    out = []
    qs, ss = np.asarray(q, dtype=float), np.asarray(seed, dtype=float)
    for a, s, (lo, hi) in zip(qs, ss, np.asarray(limits, dtype=float), strict=True):
        best = float(a)
        for k in (-1, 1):
            alt = float(a) + 360.0 * k
            if lo <= alt <= hi and abs(alt - s) < abs(best - s):
                best = alt
        out.append(best)
    return tuple(out)


def split_move(start: Sequence[float], end: Sequence[float], max_step_deg: float) -> list[tuple[float, ...]]:
    """Waypoints from ``start`` (excluded) to ``end`` (included), no joint moving more than ``max_step_deg``
    between two of them, at the controller's resolution."""
    from station.calibration import joint_steps  # scipy behind it: not at this module's import

    return [quantised(q) for q in joint_steps(start, end, max_step_deg=max_step_deg)]


def lift_pose(q: Sequence[float]) -> tuple[float, ...]:
    """Upper arm and forearm upright, the other joints where they are: the camera high above the cell."""
    return (float(q[0]), 0.0, 0.0, float(q[3]), float(q[4]), float(q[5]))


def travel(start: Sequence[float], end: Sequence[float], max_step_deg: float) -> list[tuple[float, ...]]:
    """Waypoints from one pose to another through the lift poses (up, across, down): the camera stays high
    above every artifact between them (a leg that does not move gives one waypoint where it is)."""
    up_from, up_to = lift_pose(start), lift_pose(end)
    return [
        *split_move(start, up_from, max_step_deg),
        *split_move(up_from, up_to, max_step_deg),
        *split_move(up_to, end, max_step_deg),
    ]


def step_limit(max_step_deg: float) -> float:
    """The joint step a route uses for a driver whose largest step is ``max_step_deg``."""
    return max_step_deg * STEP_MARGIN


def max_step_of(safety: Mapping[str, Any] | None) -> float:
    """The largest joint step of a robot's safety settings (``[robot] safety``), else the default."""
    value = (safety or {}).get("max_step_deg", DEFAULT_MAX_STEP_DEG)
    return float(value)


def worst_joint(here: Sequence[float], target: Sequence[float]) -> tuple[int, float]:
    """The joint (1-6) farthest from ``target`` and by how much (deg, signed: ``here - target``)."""
    d = np.asarray(here, dtype=float) - np.asarray(target, dtype=float)
    i = int(np.argmax(np.abs(d)))
    return i + 1, float(d[i])


def at_pose(
    here: Sequence[float], target: Sequence[float], tolerance_deg: float = AT_POSE_TOLERANCE_DEG
) -> bool:
    """Whether every joint of ``here`` is within ``tolerance_deg`` of ``target``."""
    return abs(worst_joint(here, target)[1]) <= tolerance_deg


def describe_offset(commanded: Sequence[float], reference: Sequence[float]) -> str:
    """``joint 4 commanded at +144.085 deg, its reference +0.000 deg`` for the joint farthest off."""
    j, _ = worst_joint(commanded, reference)
    return f"joint {j} commanded at {commanded[j - 1]:+.3f} deg, its reference {reference[j - 1]:+.3f} deg"


@dataclass(frozen=True)
class Route:
    """The waypoints from ``start_deg`` to ``target_deg`` (``moves``: each an absolute joint target, deg;
    empty when the arm is already there) and whether they go through the lift poses."""

    start_deg: tuple[float, ...]
    target_deg: tuple[float, ...]
    moves: tuple[tuple[float, ...], ...]
    via_lift: bool


def plan_route(start_deg: Sequence[float], target_deg: Sequence[float], *, max_step_deg: float) -> Route:
    """The route from ``start_deg`` to ``target_deg`` for a driver whose largest joint step is
    ``max_step_deg`` (see the module notes); pure, no device.

    Raises
    ------
    ValueError
        When either pose is not six finite angles or the step is not positive.
    """
    start = np.asarray(start_deg, dtype=float)
    target = np.asarray(target_deg, dtype=float)
    for name, pose in (("start_deg", start), ("target_deg", target)):
        if pose.shape != (JOINT_COUNT,) or not np.all(np.isfinite(pose)):
            raise ValueError(f"{name} must be {JOINT_COUNT} finite joint angles, got {pose.tolist()!r}")
    if not (np.isfinite(max_step_deg) and max_step_deg > 0):
        raise ValueError(f"max_step_deg must be a positive number, got {max_step_deg!r}")
    s, t = quantised(start), quantised(target)
    if at_pose(s, t):  # within 0.01 deg: there already
        return Route(s, t, (), False)
    limit = step_limit(max_step_deg)
    if float(np.max(np.abs(start - target))) <= limit:
        return Route(s, t, (t,), False)
    moves: list[tuple[float, ...]] = []
    for q in travel(s, t, limit):
        if q != (moves[-1] if moves else s):  # a leg that does not move (the arm already upright)
            moves.append(q)
    return Route(s, t, tuple(moves), True)


class RouteRejectedError(MotionRejectedError):
    """A move of the route failed the robot's own checks; nothing was sent. ``problems``: every one."""

    def __init__(self, problems: Sequence[str]) -> None:
        shown = "; ".join(problems[:3]) + (f"; and {len(problems) - 3} more" if len(problems) > 3 else "")
        super().__init__(
            f"the route to the reference pose is refused, nothing moved: {shown}; jog the arm clear with the"
            " pendant (the route goes up through the lift pose), then try again"
        )
        self.problems = list(problems)


def route_problems(robot: Robot, route: Route) -> list[str]:
    """Every move of ``route`` checked with ``robot.check_move`` from the previous waypoint (the first from
    ``route.start_deg``); each refusal as ``move K of N to (...): why``. No I/O."""
    problems = []
    previous: Sequence[float] = route.start_deg
    n = len(route.moves)
    for k, q in enumerate(route.moves, start=1):
        try:
            robot.check_move(q, start_deg=previous)
        except MotionRejectedError as exc:
            problems.append(f"move {k} of {n} to ({', '.join(f'{a:.3f}' for a in q)}): {exc}")
        previous = q
    return problems


class ArmPose(BaseModel):
    """Where the arm is: attained and commanded joints (deg) and the controller's WORLD row."""

    model_config = ConfigDict(frozen=True)

    joints_deg: list[float]
    commanded_joints_deg: list[float]
    world_mm_deg: list[float] | None = Field(None, description="x y z (mm), z/y/x rot (deg); None: unknown")

    @classmethod
    def of(cls, p: RobotPosition) -> ArmPose:
        return cls(
            joints_deg=list(p.joints_deg),
            commanded_joints_deg=list(p.commanded_joints_deg),
            world_mm_deg=None if p.world_mm_deg is None else list(p.world_mm_deg),
        )


class ToReferenceResult(BaseModel):
    """What ``to-reference`` did (the CLI's ``--json`` line and the API's reply alike).

    ``moves``: the joint targets sent, in order (deg; empty when the arm was already there);
    ``via_lift``: whether they went through the lift poses; ``start`` and ``final_pose``: where the arm
    was before and is after; ``at_reference``: the final commanded joints within 0.01 deg of
    ``reference_joints_deg``.
    """

    model_config = ConfigDict(frozen=True)

    reference_joints_deg: list[float]
    start: ArmPose
    moves: list[list[float]]
    via_lift: bool
    final_pose: ArmPose
    at_reference: bool


class RoutePreview(BaseModel):
    """The route ``to-reference`` would take from where the arm is: its moves (deg), whether through the
    lift poses, and every problem the robot's checks find in it (empty: it would be sent)."""

    model_config = ConfigDict(frozen=True)

    moves: list[list[float]]
    via_lift: bool
    problems: list[str]


class ArmStatus(BaseModel):
    """Where the arm is against its reference pose (``GET /api/v1/station/robot``): ``at_reference`` when
    every commanded joint is within 0.01 deg of it; ``route``: the way there from here."""

    model_config = ConfigDict(frozen=True)

    position: ArmPose
    reference_joints_deg: list[float]
    at_reference: bool
    route: RoutePreview


def robot_status(robot: Robot, reference_deg: Sequence[float], max_step_deg: float) -> ArmStatus:
    """Read where the (connected) arm is and plan and check its route to ``reference_deg``; no motion."""
    here = robot.where()
    route = plan_route(here.commanded_joints_deg, reference_deg, max_step_deg=max_step_deg)
    return ArmStatus(
        position=ArmPose.of(here),
        reference_joints_deg=list(route.target_deg),
        at_reference=not route.moves,
        route=RoutePreview(
            moves=[list(q) for q in route.moves],
            via_lift=route.via_lift,
            problems=route_problems(robot, route),
        ),
    )


def go_to_reference(
    robot: Robot,
    reference_deg: Sequence[float],
    *,
    max_step_deg: float,
    before_move: Callable[[int, tuple[float, ...]], None] | None = None,
) -> ToReferenceResult:
    """Take the arm (connected) to ``reference_deg`` along :func:`plan_route` from where it is commanded.

    Every move is checked with ``robot.check_move`` before the first is sent (:class:`RouteRejectedError`
    lists each refusal; nothing moved then); each returns once the arm has arrived. ``before_move(k,
    target)`` is called before move ``k`` (1-based) is sent. Device errors of the moves propagate (the
    arm stays where that move left it).
    """
    start = robot.where()
    route = plan_route(start.commanded_joints_deg, reference_deg, max_step_deg=max_step_deg)
    problems = route_problems(robot, route)
    if problems:
        raise RouteRejectedError(problems)
    for k, q in enumerate(route.moves, start=1):
        if before_move is not None:
            before_move(k, q)
        robot.move_joints(q)
    final = robot.where()
    return ToReferenceResult(
        reference_joints_deg=list(route.target_deg),
        start=ArmPose.of(start),
        moves=[list(q) for q in route.moves],
        via_lift=route.via_lift,
        final_pose=ArmPose.of(final),
        at_reference=at_pose(final.commanded_joints_deg, route.target_deg),
    )


__all__ = [
    "AT_POSE_TOLERANCE_DEG",
    "DEFAULT_MAX_STEP_DEG",
    "JOINT_DECIMALS",
    "TO_REFERENCE_HINT",
    "ArmPose",
    "ArmStatus",
    "Route",
    "RoutePreview",
    "RouteRejectedError",
    "ToReferenceResult",
    "at_pose",
    "describe_offset",
    "go_to_reference",
    "lift_pose",
    "max_step_of",
    "plan_route",
    "quantised",
    "robot_status",
    "route_problems",
    "split_move",
    "step_limit",
    "travel",
    "unwrap_near",
    "worst_joint",
]
