"""Host-side motion checks: joint limits, maximum step, speed cap and a Cartesian keep-out, before
anything is sent.

A motion is checked along the path the arm will actually take, not only at its end: the system shell
moves one joint at a time, so an absolute move is a sequence of single-joint moves, and a pose
between them can dip where neither end does. The guard samples every joint-space segment finely
enough that no point the arm carries moves more than ``path_resolution_mm`` between two samples (a
point at most R from a joint's axis moves at most R times the angle: R is bounded per joint from the
arm's links and the carried bodies), and at most ``path_step_deg`` per sample. At each sample it
computes the flange by forward kinematics and rejects the motion if the camera's lens front comes
closer to the table plane than allowed, the flange leaves the workspace box, or any carried body
(the wrist and flange, the camera body, the sensor head: capsules in the flange frame) comes within
``clearance_mm`` of a keep-out volume (boxes and cylinders in the base frame, ``station.keepout``);
half the resolution is added to that margin, so nothing between two samples touches a volume either.
For an absolute move it tries the axis orders in turn and keeps the first safe one.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, model_validator

from drivers.crs_a465._errors import rejected
from station.devices import JOINT_COUNT, MotionRejectedError
from station.keepout import CarriedBody, KeepOut, body_spheres, first_contact
from station.kinematics import Kinematics
from station.speed_cap import DEFAULT_MAX_SPEED_PCT, check_speed

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]


class SafetyLimits(BaseModel):
    """What the host allows: set these per station (the defaults suit an arm on the table it looks at).

    ``joint_limits_deg`` narrows the arm's own limits (``None``: the arm's). ``camera_offset_mm`` is the
    camera's front (lens) in the flange frame: the point kept ``min_camera_height_mm`` above the table
    plane ``z = table_z_mm`` (base frame); the station fills it from ``[camera] mount``. The flange
    origin must stay in the box ``workspace_min_mm``..``workspace_max_mm``. ``keep_out``: the cell's
    fixtures (boxes and cylinders, base frame) that ``wrist`` and ``carried`` (capsules in the flange
    frame; the station adds the camera body and the sensor head from their mounts) must stay
    ``clearance_mm`` clear of, along every path. ``ready_pose_deg`` is where ``ready`` goes and
    ``home_pose_deg`` where ``home`` goes, so that their paths are checked too (``None``: refused, as the
    path would be unknown). ``max_speed_pct``: the speed override no command may exceed;
    ``jog_speed_pct`` the (lower) speed of jogs.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    joint_limits_deg: tuple[tuple[float, float], ...] | None = None
    max_step_deg: float = Field(30.0, gt=0, description="largest change of any joint in one call")
    table_z_mm: float = 0.0
    min_camera_height_mm: float = Field(50.0, ge=0)
    camera_offset_mm: Vec3 = (0.0, 0.0, 100.0)
    workspace_min_mm: Vec3 = (-800.0, -800.0, 0.0)
    workspace_max_mm: Vec3 = (800.0, 800.0, 1100.0)
    ready_pose_deg: tuple[float, ...] | None = (0.0, 0.0, 90.0, 0.0, 90.0, 0.0)
    home_pose_deg: tuple[float, ...] | None = (0.0,) * JOINT_COUNT
    path_step_deg: float = Field(1.0, gt=0, le=10.0, description="largest joint change between two samples")
    path_resolution_mm: float = Field(
        2.0, gt=0, le=20.0, description="largest motion of a carried point between two samples of a path"
    )
    keep_out: tuple[KeepOut, ...] = ()
    wrist: CarriedBody | None = CarriedBody(
        name="wrist and flange", start_mm=(0.0, 0.0, -76.0), end_mm=(0.0, 0.0, 0.0), radius_mm=40.0
    )
    carried: tuple[CarriedBody, ...] = ()
    clearance_mm: float = Field(5.0, ge=0, le=200.0, description="least distance to a keep-out volume")
    max_speed_pct: float = Field(
        DEFAULT_MAX_SPEED_PCT, ge=1, le=100, description="the speed override no command may exceed (%)"
    )
    jog_speed_pct: float = Field(10.0, ge=1, le=100, description="the speed of jogs (%), at most the cap")

    @model_validator(mode="after")
    def _consistent(self) -> SafetyLimits:
        if self.joint_limits_deg is not None and (
            len(self.joint_limits_deg) != JOINT_COUNT or any(lo >= hi for lo, hi in self.joint_limits_deg)
        ):
            raise ValueError(f"joint_limits_deg must be {JOINT_COUNT} (low, high) pairs with low < high")
        if any(lo >= hi for lo, hi in zip(self.workspace_min_mm, self.workspace_max_mm, strict=True)):
            raise ValueError("workspace_min_mm must be below workspace_max_mm on every axis")
        for name in ("ready_pose_deg", "home_pose_deg"):
            pose = getattr(self, name)
            if pose is not None and len(pose) != JOINT_COUNT:
                raise ValueError(f"{name} must have {JOINT_COUNT} angles")
        if self.jog_speed_pct > self.max_speed_pct:
            raise ValueError(
                f"jog_speed_pct ({self.jog_speed_pct:g}) must not exceed max_speed_pct"
                f" ({self.max_speed_pct:g})"
            )
        names = [v.name for v in self.keep_out]
        if len(set(names)) != len(names):
            raise ValueError(f"keep_out volumes need distinct names, got {names}")
        return self

    def bodies(self) -> tuple[CarriedBody, ...]:
        """Every body the arm carries: the wrist, then ``carried``."""
        return ((self.wrist,) if self.wrist is not None else ()) + self.carried


@dataclass(frozen=True)
class PlannedMove:
    """Single-joint relative moves, in order, as they will be sent."""

    start_deg: tuple[float, ...]
    steps: tuple[tuple[int, float], ...]

    @property
    def end_deg(self) -> tuple[float, ...]:
        q = list(self.start_deg)
        for axis, delta in self.steps:
            q[axis - 1] += delta
        return tuple(q)


def _fmt(q: npt.ArrayLike) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in np.asarray(q, dtype=float).ravel()) + ")"


class MotionGuard:
    """Checks motions against :class:`SafetyLimits` with the arm's :class:`Kinematics`."""

    def __init__(self, limits: SafetyLimits | None = None, kinematics: Kinematics | None = None) -> None:
        self.limits = limits or SafetyLimits()
        self.kinematics = kinematics or Kinematics()
        arm = self.kinematics.joint_limits_deg
        if self.limits.joint_limits_deg is None:
            self.joint_limits = arm.copy()
        else:
            own = np.asarray(self.limits.joint_limits_deg, dtype=float)
            self.joint_limits = np.column_stack(
                [np.maximum(arm[:, 0], own[:, 0]), np.minimum(arm[:, 1], own[:, 1])]
            )
        self._camera_point = np.array([*self.limits.camera_offset_mm, 1.0])
        self._box_lo = np.asarray(self.limits.workspace_min_mm, dtype=float)
        self._box_hi = np.asarray(self.limits.workspace_max_mm, dtype=float)
        bodies = self.limits.bodies()
        self._spheres = body_spheres(bodies)
        self._lever_mm = self._levers(max((b.reach_mm() for b in bodies), default=0.0))

    def _levers(self, carried_reach_mm: float) -> FloatArray:
        """Per joint, a bound on how far any carried point (or the lens front) lies from that joint's
        axis: the links after it plus the carried bodies' reach from the flange."""
        rows = self.kinematics.dh
        reach = max(carried_reach_mm, float(np.linalg.norm(self.limits.camera_offset_mm)))
        links = [abs(r.a_mm) + abs(r.d_mm) for r in rows]
        return np.array([sum(links[i + 1 :]) + reach + abs(rows[i].d_mm) for i in range(JOINT_COUNT)])

    # ---------------------------------------------------------------- single checks

    @staticmethod
    def _joints(values: npt.ArrayLike, what: str) -> FloatArray:
        q = np.asarray(values, dtype=float)
        if q.shape != (JOINT_COUNT,):
            raise rejected(f"{what} must be {JOINT_COUNT} joint angles, got {q.tolist()!r}")
        if not np.all(np.isfinite(q)):
            raise rejected(f"{what} must be finite, got {_fmt(q)}")
        return q

    def check_limits(self, joints_deg: npt.ArrayLike, *, what: str = "target") -> None:
        """Reject joints outside the (narrowed) joint limits."""
        q = self._joints(joints_deg, what)
        for i in range(JOINT_COUNT):
            lo, hi = self.joint_limits[i]
            if not lo <= q[i] <= hi:
                raise rejected(
                    f"{what}: joint {i + 1} at {q[i]:.3f} deg is outside its limits [{lo:g}, {hi:g}]"
                )

    def check_step(self, start_deg: npt.ArrayLike, end_deg: npt.ArrayLike) -> None:
        """Reject a call that changes any joint by more than ``max_step_deg``."""
        delta = self._joints(end_deg, "target") - self._joints(start_deg, "start")
        i = int(np.argmax(np.abs(delta)))
        if abs(delta[i]) > self.limits.max_step_deg + 1e-9:
            raise rejected(
                f"joint {i + 1} would move {delta[i]:+.3f} deg, more than the maximum step of"
                f" {self.limits.max_step_deg:g} deg; move in smaller steps or raise max_step_deg"
            )

    def check_speed(self, percent: float) -> None:
        """Reject a speed override above ``max_speed_pct`` (SpeedCapError, saying where the cap is set)."""
        check_speed(percent, self.limits.max_speed_pct)

    def keepout_violation(self, path_deg: npt.ArrayLike, *, margin_mm: float | None = None) -> str | None:
        """Why the first pose of ``path_deg`` (N x 6) that breaks the keep-out does so, or None.

        ``margin_mm``: how close a carried body may come to a keep-out volume (default
        ``clearance_mm``; a path adds half its sampling's resolution).
        """
        q = np.atleast_2d(np.asarray(path_deg, dtype=float))
        flanges = self.kinematics.flange(q)
        flange_xyz = flanges[:, :3, 3]
        camera_z = (flanges @ self._camera_point)[:, 2]
        floor = self.limits.table_z_mm + self.limits.min_camera_height_mm
        low = camera_z < floor - 1e-9
        outside = np.any((flange_xyz < self._box_lo - 1e-9) | (flange_xyz > self._box_hi + 1e-9), axis=1)
        margin = self.limits.clearance_mm if margin_mm is None else margin_mm
        contact = first_contact(flanges, self._spheres, self.limits.keep_out, margin_mm=margin)
        bad = np.flatnonzero(low | outside)
        if contact is not None and (bad.size == 0 or contact.pose_index < bad[0]):
            return (
                f"the {contact.body} would come within {max(contact.clearance_mm, 0.0):.1f} mm of the"
                f" keep-out volume {contact.volume!r} (clearance {self.limits.clearance_mm:g} mm) at joints"
                f" {_fmt(q[contact.pose_index])}"
            )
        if bad.size == 0:
            return None
        k = int(bad[0])
        if low[k]:
            return (
                f"the camera would come to {camera_z[k] - self.limits.table_z_mm:.1f} mm above the table"
                f" (minimum {self.limits.min_camera_height_mm:g} mm) at joints {_fmt(q[k])}"
            )
        return (
            f"the flange would leave the workspace box at ({flange_xyz[k, 0]:.1f}, {flange_xyz[k, 1]:.1f},"
            f" {flange_xyz[k, 2]:.1f}) mm, joints {_fmt(q[k])}"
        )

    def segment_samples(self, start: npt.ArrayLike, end: npt.ArrayLike) -> int:
        """How many intervals a straight joint-space segment is sampled in: no carried point moves more
        than ``path_resolution_mm`` and no joint more than ``path_step_deg`` between two samples."""
        delta = np.abs(np.asarray(end, dtype=float) - np.asarray(start, dtype=float))
        by_angle = float(np.max(delta)) / self.limits.path_step_deg
        by_motion = float(np.radians(delta) @ self._lever_mm) / self.limits.path_resolution_mm
        return max(1, math.ceil(max(by_angle, by_motion)))

    def _segment(self, start: FloatArray, end: FloatArray) -> FloatArray:
        t = np.linspace(0.0, 1.0, self.segment_samples(start, end) + 1)[:, None]
        return np.asarray(start + t * (end - start), dtype=float)

    def path_violation(self, waypoints: Sequence[npt.ArrayLike]) -> str | None:
        """Keep-out check along straight joint-space segments between ``waypoints``."""
        points = [np.asarray(w, dtype=float) for w in waypoints]
        samples = [self._segment(a, b) for a, b in itertools.pairwise(points)] or [np.atleast_2d(points[0])]
        margin = self.limits.clearance_mm + self.limits.path_resolution_mm / 2.0
        return self.keepout_violation(np.vstack(samples), margin_mm=margin)

    # ---------------------------------------------------------------- whole motions

    def check_linear(
        self, start_deg: Sequence[float], end_deg: Sequence[float], *, step: bool = True
    ) -> None:
        """Check a move interpolated in joint space (all joints together), e.g. ``ready``."""
        start = self._joints(start_deg, "start")
        end = self._joints(end_deg, "target")
        self.check_limits(end)
        if step:
            self.check_step(start, end)
        why = self.path_violation([start, end])
        if why is not None:
            raise rejected(why)

    def check_home(self, start_deg: Sequence[float], home_deg: Sequence[float]) -> None:
        """Check ``home``'s two possible paths to ``home_deg``: all joints together, and one axis at a
        time in the order 1 to 6 (how the controller homes [F]); no step limit (the controller moves)."""
        start = self._joints(start_deg, "start")
        end = self._joints(home_deg, "home pose")
        self.check_limits(end, what="home pose")
        why = self.path_violation([start, end])
        if why is None:
            q, waypoints = start.copy(), [start]
            for i in range(JOINT_COUNT):
                q = q.copy()
                q[i] = end[i]
                waypoints.append(q)
            why = self.path_violation(waypoints)
        if why is not None:
            raise rejected(f"home from {_fmt(start)}: {why}; take the arm somewhere safe first")

    def plan_single_joint_moves(
        self, start_deg: npt.ArrayLike, steps: Sequence[tuple[int, float]]
    ) -> PlannedMove:
        """Check single-joint ``steps`` (axis, delta) from ``start_deg``; try other orders if needed.

        Deltas are used as given (already rounded to what will be sent). Returns the safe order.
        """
        start = self._joints(start_deg, "start")
        moving = [(axis, delta) for axis, delta in steps if delta != 0.0]
        end = start.copy()
        for axis, delta in moving:
            end[axis - 1] += delta
        self.check_limits(end)
        self.check_step(start, end)
        first_reason: str | None = None
        for order in itertools.permutations(moving):
            waypoints = [start]
            q = start.copy()
            for axis, delta in order:
                q = q.copy()
                q[axis - 1] += delta
                waypoints.append(q)
            why = self.path_violation(waypoints)
            if why is None:
                if first_reason is not None:
                    log.info(
                        "axis order %s chosen: the natural order fails (%s)",
                        [a for a, _ in order],
                        first_reason,
                    )
                return PlannedMove(tuple(float(v) for v in start), tuple(order))
            first_reason = first_reason or why
        raise MotionRejectedError(
            f"no order of single-joint moves from {_fmt(start)} to {_fmt(end)} stays clear of the keep-out:"
            f" {first_reason}; nothing was sent to the controller"
        )


__all__ = ["MotionGuard", "PlannedMove", "SafetyLimits"]
