"""Jogging: small moves of one joint, or of the camera in its own frame, at a reduced, capped speed.

A camera-frame jog moves the camera along its own x or y (the image's right and down), along its
optical axis (z: + toward what it looks at, OpenCV's camera frame), or turns it about the optical
axis (``turn``, deg, right-handed about +z), through the station's *nominal* model: the arm's nominal
kinematics with the camera's mounting as the tool (``[camera] mount``). No calibration is needed: over
a jog of a few millimetres the nominal model's error is a fraction of a micrometre per millimetre,
which is what "accurate enough to jog" means here. Pure functions (:func:`camera_jog_target`,
:func:`joint_jog_target`) give the joint target; :func:`jog` checks it on the robot (limits, step,
keep-out along the path, the speed cap) before anything is sent, sets the jog speed and moves.

Used by ``station robot --config F jog ...`` and, later, by the service's jog route and the page's jog
panel (``JOG_STEPS_MM`` / ``JOG_STEPS_DEG`` are the steps they offer).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from station.devices import JOINT_COUNT, MotionRejectedError, Robot, RobotPosition
from station.kinematics import Kinematics, UnreachableError, rot_z, transform

__all__ = [
    "CAMERA_AXES",
    "JOG_SPEED_PCT",
    "JOG_STEPS_DEG",
    "JOG_STEPS_MM",
    "MAX_CAMERA_JOG_DEG",
    "MAX_CAMERA_JOG_MM",
    "MAX_JOINT_JOG_DEG",
    "JogError",
    "JogResult",
    "camera_jog_target",
    "camera_offset_target",
    "jog",
    "joint_jog_target",
]

FloatArray = npt.NDArray[np.float64]
CameraAxis = Literal["x", "y", "z", "turn"]
CAMERA_AXES: tuple[CameraAxis, ...] = ("x", "y", "z", "turn")

JOG_STEPS_MM = (0.01, 0.1, 1.0, 5.0)
"""The camera-frame steps a jog panel offers (mm)."""
JOG_STEPS_DEG = (0.01, 0.1, 1.0, 5.0)
"""The joint and turn steps a jog panel offers (deg)."""
MAX_JOINT_JOG_DEG = 10.0
"""The largest joint jog (deg): a larger move is a move, not a jog."""
MAX_CAMERA_JOG_MM = 10.0
"""The largest camera-frame jog along an axis (mm)."""
MAX_CAMERA_JOG_DEG = 10.0
"""The largest camera turn in one jog (deg)."""
MAX_JOINT_CHANGE_DEG = 15.0
"""A camera jog that would turn any joint more than this is near a singularity: refused."""
JOG_SPEED_PCT = 10.0
"""The jog speed when the robot's settings do not give one (%), always within the station's cap."""
JOINT_DECIMALS = 3


class JogError(MotionRejectedError):
    """A jog that cannot be done as asked (bad axis or size, unreachable, near a singularity); nothing
    was sent."""


@dataclass(frozen=True)
class JogResult:
    """What a jog did: ``start_deg`` and ``target_deg`` (commanded joints), the speed it ran at, and where
    the arm is after it (``final``)."""

    kind: Literal["joint", "camera"]
    axis: str
    delta: float
    start_deg: tuple[float, ...]
    target_deg: tuple[float, ...]
    speed_pct: float
    final: RobotPosition

    def to_dict(self) -> dict[str, object]:
        return {
            "kind": self.kind,
            "axis": self.axis,
            "delta": self.delta,
            "unit": "mm" if self.kind == "camera" and self.axis != "turn" else "deg",
            "start_joints_deg": list(self.start_deg),
            "target_joints_deg": list(self.target_deg),
            "speed_pct": self.speed_pct,
            "joints_deg": list(self.final.joints_deg),
            "commanded_joints_deg": list(self.final.commanded_joints_deg),
            "world_mm_deg": None if self.final.world_mm_deg is None else list(self.final.world_mm_deg),
        }


def _quantised(q: npt.ArrayLike) -> tuple[float, ...]:
    return tuple(round(float(a), JOINT_DECIMALS) for a in np.asarray(q, dtype=np.float64))


def _finite(delta: float, what: str) -> float:
    try:
        value = float(delta)
    except (TypeError, ValueError):
        raise JogError(f"{what} must be a number, got {delta!r}; nothing was sent") from None
    if not math.isfinite(value):
        raise JogError(f"{what} must be finite, got {delta!r}; nothing was sent")
    return value


def joint_jog_target(start_deg: Sequence[float], axis: int, delta_deg: float) -> tuple[float, ...]:
    """The joints after jogging joint ``axis`` (1-6) by ``delta_deg`` (at most :data:`MAX_JOINT_JOG_DEG`)."""
    if isinstance(axis, bool) or not isinstance(axis, int) or not 1 <= axis <= JOINT_COUNT:
        raise JogError(f"joint must be 1 to {JOINT_COUNT}, got {axis!r}; nothing was sent")
    delta = _finite(delta_deg, "the joint jog")
    if abs(delta) > MAX_JOINT_JOG_DEG:
        raise JogError(
            f"a joint jog is at most {MAX_JOINT_JOG_DEG:g} deg, got {delta:+g}; jog in smaller steps or use"
            " move-joints; nothing was sent"
        )
    q = [float(v) for v in start_deg]
    q[axis - 1] += delta
    return _quantised(q)


def camera_motion(axis: CameraAxis, delta: float) -> FloatArray:
    """The jog as a 4x4 motion in the camera's own frame (mm, deg)."""
    if axis == "turn":
        return transform(rot_z(math.radians(delta)), (0.0, 0.0, 0.0))
    shift = {"x": (delta, 0.0, 0.0), "y": (0.0, delta, 0.0), "z": (0.0, 0.0, delta)}[axis]
    return transform(np.eye(3), shift)


def camera_jog_target(
    start_deg: Sequence[float], nominal: Kinematics, axis: str, delta: float
) -> tuple[float, ...]:
    """The joints that move the camera by ``delta`` along (or, ``turn``, about) its own ``axis``.

    ``nominal``: the arm's nominal kinematics with the camera's mounting as its tool
    (``Kinematics(tool=camera_mount.matrix())``). ``x``/``y``: the image's right/down (mm); ``z``: along
    the optical axis, + toward what the camera looks at (mm); ``turn``: about the optical axis (deg).
    The solution nearest ``start_deg``; refused (:class:`JogError`) when unreachable or when a joint would
    turn more than :data:`MAX_JOINT_CHANGE_DEG` (a singularity: the wrist straight).
    """
    if axis not in CAMERA_AXES:
        raise JogError(
            f"a camera jog's axis is one of {', '.join(CAMERA_AXES)}, got {axis!r}; nothing was sent"
        )
    value = _finite(delta, "the camera jog")
    limit = MAX_CAMERA_JOG_DEG if axis == "turn" else MAX_CAMERA_JOG_MM
    if abs(value) > limit:
        unit = "deg" if axis == "turn" else "mm"
        raise JogError(
            f"a camera jog is at most {limit:g} {unit}, got {value:+g} {unit}; jog in smaller steps;"
            " nothing was sent"
        )
    start = np.asarray(start_deg, dtype=np.float64)
    target_pose = nominal.forward(start) @ camera_motion(axis, value)
    try:
        q = nominal.inverse(target_pose, seed_deg=start)
    except UnreachableError as exc:
        raise JogError(f"the camera cannot be jogged there ({exc}); nothing was sent") from exc
    change = np.abs(q - start)
    worst = int(np.argmax(change))
    if change[worst] > MAX_JOINT_CHANGE_DEG:
        raise JogError(
            f"jogging the camera {axis} by {value:+g} would turn joint {worst + 1} by"
            f" {change[worst]:.1f} deg: the arm is near a singularity (the wrist straight); jog a joint"
            " instead; nothing was sent"
        )
    return _quantised(q)


def camera_offset_target(
    start_deg: Sequence[float], nominal: Kinematics, offset_mm: Sequence[float]
) -> tuple[float, ...]:
    """The joints that shift the camera by ``offset_mm`` (x, y, z in its own frame; no turn) from
    ``start_deg``, through the nominal model; no jog-size limit (the robot's checks still apply), the
    singularity guard of :func:`camera_jog_target`."""
    start = np.asarray(start_deg, dtype=np.float64)
    target_pose = nominal.forward(start) @ transform(np.eye(3), [float(v) for v in offset_mm])
    try:
        q = nominal.inverse(target_pose, seed_deg=start)
    except UnreachableError as exc:
        raise JogError(f"the camera cannot be moved there ({exc}); nothing was sent") from exc
    if float(np.max(np.abs(q - start))) > 4 * MAX_JOINT_CHANGE_DEG:
        raise JogError("that camera shift would swing the arm through a singularity; nothing was sent")
    return _quantised(q)


def jog(
    robot: Robot,
    *,
    joint: int | None = None,
    camera_axis: str | None = None,
    delta: float,
    nominal: Kinematics | None = None,
    speed_pct: float = JOG_SPEED_PCT,
) -> JogResult:
    """Jog ``robot`` (connected): one joint (``joint``, deg) or the camera (``camera_axis``, with the
    ``nominal`` model), at ``speed_pct`` (which the robot's cap bounds).

    Everything is checked before anything is sent: the target (limits, step, keep-out along the path:
    ``check_move`` from the commanded position) and the speed (``check_speed``); then the speed is set and
    the arm moved. A refusal raises ``MotionRejectedError`` (:class:`JogError`, ``SpeedCapError``) and
    nothing moves; a latched stop raises ``StopLatchedError``.
    """
    if (joint is None) == (camera_axis is None):
        raise JogError("jog one joint or the camera along one axis; nothing was sent")
    start = tuple(float(v) for v in robot.where().commanded_joints_deg)
    if joint is not None:
        target = joint_jog_target(start, joint, delta)
        kind: Literal["joint", "camera"] = "joint"
        axis = str(joint)
    else:
        if nominal is None:
            raise JogError("a camera jog needs the nominal model with the camera's mounting (--config)")
        assert camera_axis is not None
        target = camera_jog_target(start, nominal, camera_axis, delta)
        kind, axis = "camera", camera_axis
    robot.check_move(target, start_deg=start)
    robot.check_speed(speed_pct)
    robot.set_speed(speed_pct)
    robot.move_joints(target)
    return JogResult(kind, axis, float(delta), start, target, float(speed_pct), robot.where())
