"""Host-side motion checks: joint limits, maximum step and a Cartesian keep-out, before anything is sent.

A motion is checked along the path the arm will actually take, not only at its end: the system shell
moves one joint at a time, so an absolute move is a sequence of single-joint moves, and a pose
between them can dip where neither end does. The guard samples every segment (at most
``path_step_deg`` per sample), computes the flange and camera positions by forward kinematics, and
rejects the motion if the camera comes closer to the table plane than allowed or the flange leaves
the workspace box. For an absolute move it tries the axis orders in turn and keeps the first safe one.
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
from station.kinematics import Kinematics

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]


class SafetyLimits(BaseModel):
    """What the host allows: set these per station (the defaults suit an arm on the table it looks at).

    ``joint_limits_deg`` narrows the arm's own limits (``None``: the arm's). ``camera_offset_mm`` is the
    camera's front (lens) in the flange frame: the point kept ``min_camera_height_mm`` above the table
    plane ``z = table_z_mm`` (base frame). The flange origin must stay in the box
    ``workspace_min_mm``..``workspace_max_mm``. ``ready_pose_deg`` is where ``ready`` goes, so that it can
    be checked too (``None``: not checked). ``home`` moves as the controller decides and is not checked.
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
    path_step_deg: float = Field(1.0, gt=0, le=10.0, description="sampling of a path for the keep-out")

    @model_validator(mode="after")
    def _consistent(self) -> SafetyLimits:
        if self.joint_limits_deg is not None and (
            len(self.joint_limits_deg) != JOINT_COUNT or any(lo >= hi for lo, hi in self.joint_limits_deg)
        ):
            raise ValueError(f"joint_limits_deg must be {JOINT_COUNT} (low, high) pairs with low < high")
        if any(lo >= hi for lo, hi in zip(self.workspace_min_mm, self.workspace_max_mm, strict=True)):
            raise ValueError("workspace_min_mm must be below workspace_max_mm on every axis")
        if self.ready_pose_deg is not None and len(self.ready_pose_deg) != JOINT_COUNT:
            raise ValueError(f"ready_pose_deg must have {JOINT_COUNT} angles")
        return self


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

    def keepout_violation(self, path_deg: npt.ArrayLike) -> str | None:
        """Why the first pose of ``path_deg`` (N x 6) that breaks the keep-out does so, or None."""
        q = np.atleast_2d(np.asarray(path_deg, dtype=float))
        flanges = self.kinematics.flange(q)
        flange_xyz = flanges[:, :3, 3]
        camera_z = (flanges @ self._camera_point)[:, 2]
        floor = self.limits.table_z_mm + self.limits.min_camera_height_mm
        low = camera_z < floor - 1e-9
        outside = np.any((flange_xyz < self._box_lo - 1e-9) | (flange_xyz > self._box_hi + 1e-9), axis=1)
        bad = np.flatnonzero(low | outside)
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

    def _segment(self, start: FloatArray, end: FloatArray) -> FloatArray:
        span = float(np.max(np.abs(end - start)))
        n = max(1, math.ceil(span / self.limits.path_step_deg))
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        return np.asarray(start + t * (end - start), dtype=float)

    def path_violation(self, waypoints: Sequence[npt.ArrayLike]) -> str | None:
        """Keep-out check along straight joint-space segments between ``waypoints``."""
        points = [np.asarray(w, dtype=float) for w in waypoints]
        samples = [self._segment(a, b) for a, b in itertools.pairwise(points)] or [np.atleast_2d(points[0])]
        return self.keepout_violation(np.vstack(samples))

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
