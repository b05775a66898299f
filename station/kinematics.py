"""Forward and inverse kinematics of the CRS A465 from a modified (Craig) Denavit-Hartenberg table.

Used by the robot driver (keep-out checks before any motion is sent), by the controller twin (its
WORLD row and nothing else) and, later, by the kinematic calibration (a calibrated table is just
another ``Kinematics``). Units: mm and degrees at the interface, radians inside.

Conventions
-----------
* Link transform (modified DH): ``T(i-1, i) = RotX(alpha(i-1)) TransX(a(i-1)) RotY(beta(i-1)) RotZ(theta_i)
  TransZ(d_i)`` with ``theta_i = q_i + theta_offset_i``. ``beta`` is Hayati's extra rotation [3], zero in
  the nominal table: where two consecutive axes are nominally parallel (joints 2 and 3 of the A465), a
  small tilt between them about the common normal's perpendicular cannot be written with DH's four
  parameters without a huge jump of ``d``; ``beta`` expresses it smoothly.
* ``flange(q)`` is the flange frame in the base frame (``base @ T01 ... T56``); ``tool_pose(q)`` is
  ``flange(q) @ tool``: with the camera's transform as ``tool`` it is the camera frame.
* The controller's WORLD row ``(x, y, z, z_rot, y_rot, x_rot)`` is read as
  ``R = RotZ(z_rot) RotY(y_rot) RotX(x_rot)`` (yaw-pitch-roll): an assumption to check on a real
  C500C (drivers/crs_a465/DIALECT.md, "WORLD's rotation order"). Only :func:`world_row` and
  :func:`pose_from_world_row` depend on it.

References
----------
.. [1] J. J. Craig, *Introduction to Robotics: Mechanics and Control*, 3rd ed., ch. 3 (modified DH).
.. [2] RoboDK robot library, CRS A465 (republished in ``SaltworkerMLU/robotkinematicscatalogue``):
       the table :data:`A465_DH` and the joint limits :data:`A465_JOINT_LIMITS_DEG`.
.. [3] S. Hayati, M. Mirmirani, "Improving the absolute positioning accuracy of robot manipulators",
       *J. Robotic Systems* 2(4), 1985 (the parallel-axes modification).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
JOINTS = 6


class KinematicsError(ValueError):
    """A kinematic request that cannot be met (bad input, unreachable pose)."""


class UnreachableError(KinematicsError):
    """No joint solution within the joint limits reaches the requested pose."""


@dataclass(frozen=True)
class DHRow:
    """One row of a modified DH table: ``alpha(i-1)``, ``a(i-1)``, ``d(i)``, theta offset, and Hayati's
    ``beta(i-1)`` (rotation about y after ``a``; 0 in a nominal table)."""

    alpha_deg: float
    a_mm: float
    d_mm: float
    theta_offset_deg: float = 0.0
    beta_deg: float = 0.0


A465_DH: tuple[DHRow, ...] = (
    DHRow(0.0, 0.0, 330.0, 0.0),
    DHRow(-90.0, 0.0, 0.0, -90.0),
    DHRow(0.0, 305.0, 0.0, -90.0),
    DHRow(-90.0, 0.0, 330.0, 0.0),
    DHRow(90.0, 0.0, 0.0, 0.0),
    DHRow(-90.0, 0.0, 76.0, 180.0),
)
"""The nominal A465 table (mm, deg) [2]: all joints 0 puts the flange at (0, 0, 1041)."""

A465_JOINT_LIMITS_DEG: tuple[tuple[float, float], ...] = (
    (-175.0, 175.0),
    (-90.0, 90.0),
    (-110.0, 110.0),
    (-180.0, 180.0),
    (-105.0, 105.0),
    (-180.0, 180.0),
)
"""Joint limits (deg) of the A465 [2]."""


# --------------------------------------------------------------------------- small transforms


def rot_x(angle_rad: float) -> FloatArray:
    """3x3 rotation about x."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle_rad: float) -> FloatArray:
    """3x3 rotation about y."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle_rad: float) -> FloatArray:
    """3x3 rotation about z."""
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


#: The camera looking straight down (its z along the base's -z), image x along the base's -x: the sim
#: world's reference orientation and the calibration plan's; a turn about the optical axis goes on top.
LOOK_DOWN = np.diag([-1.0, 1.0, -1.0])


def square_on(normal: npt.ArrayLike) -> FloatArray:
    """The smallest rotation taking the base's +z to ``normal`` (an artifact's upward normal): the camera
    square to that artifact looks along ``-normal`` with ``square_on(normal) @ LOOK_DOWN``."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, n)
    s, c = float(np.linalg.norm(v)), float(z @ n)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.asarray(np.eye(3) + K + K @ K * ((1.0 - c) / (s * s)), dtype=float)


def transform(rotation: npt.ArrayLike, translation_mm: npt.ArrayLike) -> FloatArray:
    """4x4 homogeneous transform from a 3x3 rotation and a translation (mm)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(rotation, dtype=float)
    T[:3, 3] = np.asarray(translation_mm, dtype=float)
    return T


def pose_from_world_row(row: Sequence[float]) -> FloatArray:
    """4x4 pose from a WORLD row ``(x, y, z, z_rot, y_rot, x_rot)`` (mm, deg); see the module notes."""
    if len(row) != 6:
        raise KinematicsError(f"a WORLD row has 6 values (x, y, z, z_rot, y_rot, x_rot), got {len(row)}")
    x, y, z, zr, yr, xr = (float(v) for v in row)
    R = rot_z(math.radians(zr)) @ rot_y(math.radians(yr)) @ rot_x(math.radians(xr))
    return transform(R, (x, y, z))


def world_row(pose: npt.ArrayLike) -> tuple[float, float, float, float, float, float]:
    """The WORLD row ``(x, y, z, z_rot, y_rot, x_rot)`` (mm, deg) of a 4x4 pose; see the module notes.

    At ``y_rot = +/-90`` (gimbal lock) ``x_rot`` is reported as 0 and ``z_rot`` carries the rotation.
    """
    T = np.asarray(pose, dtype=float)
    R = T[:3, :3]
    sy = -R[2, 0]
    if abs(sy) < 1.0 - 1e-12:
        y_rot = math.asin(max(-1.0, min(1.0, sy)))
        z_rot = math.atan2(R[1, 0], R[0, 0])
        x_rot = math.atan2(R[2, 1], R[2, 2])
    else:  # gimbal lock: R = RotZ(z) RotY(+-90) RotX(x) depends on z -+ x only
        y_rot = math.copysign(math.pi / 2, sy)
        x_rot = 0.0
        z_rot = math.atan2(-R[0, 1], R[1, 1])
    return (
        float(T[0, 3]),
        float(T[1, 3]),
        float(T[2, 3]),
        math.degrees(z_rot),
        math.degrees(y_rot),
        math.degrees(x_rot),
    )


def _wrap_rad(angle: FloatArray | float) -> FloatArray:
    """Wrap to (-pi, pi]."""
    return np.asarray(-((-np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi), dtype=float)


def _rotation_error(R_target: FloatArray, R: FloatArray) -> FloatArray:
    """Rotation vector (rad, base frame) that turns ``R`` into ``R_target``."""
    E = R_target @ R.T
    cos_angle = max(-1.0, min(1.0, (np.trace(E) - 1.0) / 2.0))
    angle = math.acos(cos_angle)
    v = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]]) / 2.0
    if angle < 1e-9:
        return np.asarray(v, dtype=float)
    if math.pi - angle < 1e-6:  # near 180 deg: axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(E) + 1.0) / 2.0, 0.0))
        i = int(np.argmax(axis))
        axis = (E[:, i] + E[i, :]) / 2.0
        axis[i] = math.sqrt(max((E[i, i] + 1.0) / 2.0, 0.0))
        axis /= np.linalg.norm(axis)
        return np.asarray(axis * angle, dtype=float)
    return np.asarray(v * (angle / math.sin(angle)), dtype=float)


# --------------------------------------------------------------------------- the model


class Kinematics:
    """A six-joint serial arm from a modified DH table, with joint limits and a tool (camera) transform.

    Parameters
    ----------
    dh
        Six :class:`DHRow` (mm, deg); the nominal A465 by default. A calibrated table is passed the same way.
    joint_limits_deg
        Six ``(low, high)`` pairs (deg).
    tool
        4x4 flange-to-tool transform (mm); identity by default. For the station it is the camera frame.
    base
        4x4 world-to-base transform (mm); identity by default (results are then in the base frame).
    """

    def __init__(
        self,
        dh: Sequence[DHRow] = A465_DH,
        *,
        joint_limits_deg: Sequence[tuple[float, float]] = A465_JOINT_LIMITS_DEG,
        tool: npt.ArrayLike | None = None,
        base: npt.ArrayLike | None = None,
    ) -> None:
        if len(dh) != JOINTS:
            raise KinematicsError(f"dh must have {JOINTS} rows, got {len(dh)}")
        limits = np.asarray(joint_limits_deg, dtype=float)
        if limits.shape != (JOINTS, 2) or np.any(limits[:, 0] >= limits[:, 1]):
            raise KinematicsError(
                f"joint_limits_deg must be {JOINTS} (low, high) pairs with low < high,"
                f" got {joint_limits_deg!r}"
            )
        self.dh: tuple[DHRow, ...] = tuple(dh)
        self.joint_limits_deg: FloatArray = limits
        self.tool: FloatArray = self._checked_transform(tool, "tool")
        self.base: FloatArray = self._checked_transform(base, "base")
        self._alpha = np.radians([r.alpha_deg for r in self.dh])
        self._a = np.array([r.a_mm for r in self.dh], dtype=float)
        self._d = np.array([r.d_mm for r in self.dh], dtype=float)
        self._offset = np.radians([r.theta_offset_deg for r in self.dh])
        self._beta = np.radians([r.beta_deg for r in self.dh])
        # RotY(beta) as a constant 4x4 per row, None when every beta is 0 (the nominal table)
        self._beta_rot: FloatArray | None = None
        if np.any(self._beta != 0.0):
            self._beta_rot = np.stack([transform(rot_y(float(b)), (0.0, 0.0, 0.0)) for b in self._beta])

    @staticmethod
    def _checked_transform(value: npt.ArrayLike | None, name: str) -> FloatArray:
        if value is None:
            return np.eye(4)
        T = np.array(value, dtype=float)
        if T.shape != (4, 4) or not np.allclose(T[3], [0, 0, 0, 1]):
            raise KinematicsError(f"{name} must be a 4x4 homogeneous transform, got shape {T.shape}")
        if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9):
            raise KinematicsError(f"{name} rotation is not orthonormal")
        return T

    def with_tool(self, tool: npt.ArrayLike | None) -> Kinematics:
        """The same arm with another tool transform."""
        return Kinematics(self.dh, joint_limits_deg=self.joint_limits_deg.tolist(), tool=tool, base=self.base)

    # ---------------------------------------------------------------- forward

    @staticmethod
    def _as_joints(joints_deg: npt.ArrayLike) -> FloatArray:
        q = np.asarray(joints_deg, dtype=float)
        if q.shape[-1:] != (JOINTS,):
            raise KinematicsError(f"joints_deg must end in {JOINTS} angles, got shape {q.shape}")
        if not np.all(np.isfinite(q)):
            raise KinematicsError(f"joints_deg must be finite, got {q.tolist()}")
        return q

    def link_frames(self, joints_deg: npt.ArrayLike) -> FloatArray:
        """Frames 1..6 in the world frame for each set of joints: shape ``(..., 6, 4, 4)``."""
        q = np.radians(self._as_joints(joints_deg))
        theta = q + self._offset
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = np.cos(self._alpha), np.sin(self._alpha)
        A = np.zeros((*q.shape, 4, 4))
        A[..., 0, 0] = ct
        A[..., 0, 1] = -st
        A[..., 0, 3] = self._a
        A[..., 1, 0] = st * ca
        A[..., 1, 1] = ct * ca
        A[..., 1, 2] = -sa
        A[..., 1, 3] = -sa * self._d
        A[..., 2, 0] = st * sa
        A[..., 2, 1] = ct * sa
        A[..., 2, 2] = ca
        A[..., 2, 3] = ca * self._d
        A[..., 3, 3] = 1.0
        if self._beta_rot is not None:  # RotX(alpha) TransX(a) RotY(beta) RotZ(theta) TransZ(d)
            Z = np.zeros_like(A)
            Z[..., 0, 0] = ct
            Z[..., 0, 1] = -st
            Z[..., 1, 0] = st
            Z[..., 1, 1] = ct
            Z[..., 2, 2] = 1.0
            Z[..., 2, 3] = self._d
            Z[..., 3, 3] = 1.0
            X = np.zeros((JOINTS, 4, 4))
            X[:, 0, 0] = 1.0
            X[:, 0, 3] = self._a
            X[:, 1, 1] = ca
            X[:, 1, 2] = -sa
            X[:, 2, 1] = sa
            X[:, 2, 2] = ca
            X[:, 3, 3] = 1.0
            A = (X @ self._beta_rot) @ Z
        frames = np.empty_like(A)
        current = np.broadcast_to(self.base, (*q.shape[:-1], 4, 4))
        for i in range(JOINTS):
            current = current @ A[..., i, :, :]
            frames[..., i, :, :] = current
        return frames

    def flange(self, joints_deg: npt.ArrayLike) -> FloatArray:
        """Flange pose(s) (4x4, mm) for joints (deg) of shape ``(6,)`` or ``(N, 6)``."""
        return np.asarray(self.link_frames(joints_deg)[..., JOINTS - 1, :, :], dtype=float)

    def tool_pose(self, joints_deg: npt.ArrayLike) -> FloatArray:
        """Tool (camera) pose(s): ``flange @ tool``."""
        return np.asarray(self.flange(joints_deg) @ self.tool, dtype=float)

    def forward(self, joints_deg: npt.ArrayLike, *, tool: bool = True) -> FloatArray:
        """Pose of the tool (``tool=True``) or of the flange, 4x4 (mm)."""
        return self.tool_pose(joints_deg) if tool else self.flange(joints_deg)

    # ---------------------------------------------------------------- limits

    def limit_violations(self, joints_deg: npt.ArrayLike) -> list[tuple[int, float, float, float]]:
        """``(axis 1-6, value, low, high)`` for each joint outside its limits."""
        q = self._as_joints(joints_deg)
        out = []
        for i in range(JOINTS):
            low, high = self.joint_limits_deg[i]
            if not low <= q[i] <= high:
                out.append((i + 1, float(q[i]), float(low), float(high)))
        return out

    def within_limits(self, joints_deg: npt.ArrayLike, *, margin_deg: float = 0.0) -> bool:
        """True when every joint is inside its limits by at least ``margin_deg``."""
        q = self._as_joints(joints_deg)
        lo = self.joint_limits_deg[:, 0] + margin_deg
        hi = self.joint_limits_deg[:, 1] - margin_deg
        return bool(np.all((q >= lo) & (q <= hi)))

    # ---------------------------------------------------------------- inverse

    def jacobian(self, joints_deg: npt.ArrayLike, *, tool: bool = True) -> FloatArray:
        """Geometric Jacobian (6x6) of the tool or flange: rows ``(v mm/rad, w rad/rad)``, base frame."""
        frames = self.link_frames(joints_deg)
        end = frames[JOINTS - 1] @ self.tool if tool else frames[JOINTS - 1]
        p = end[:3, 3]
        J = np.empty((6, JOINTS))
        for i in range(JOINTS):
            z = frames[i, :3, 2]
            J[:3, i] = np.cross(z, p - frames[i, :3, 3])
            J[3:, i] = z
        return J

    def _refine(self, q0_deg: FloatArray, target: FloatArray, *, tool: bool) -> FloatArray | None:
        """Newton-Raphson (damped least squares) on the full pose; None when it does not converge."""
        q = np.radians(q0_deg)
        for _ in range(30):
            T = self.forward(np.degrees(q), tool=tool)
            err = np.concatenate([target[:3, 3] - T[:3, 3], _rotation_error(target[:3, :3], T[:3, :3])])
            if np.linalg.norm(err[:3]) < 1e-11 and np.linalg.norm(err[3:]) < 1e-13:
                return np.asarray(np.degrees(q), dtype=float)
            J = self.jacobian(np.degrees(q), tool=tool)
            damping = 1e-9
            step = J.T @ np.linalg.solve(J @ J.T + damping * np.eye(6), err)
            q = q + step
        T = self.forward(np.degrees(q), tool=tool)
        if np.linalg.norm(target[:3, 3] - T[:3, 3]) < 1e-7 and np.allclose(
            T[:3, :3], target[:3, :3], atol=1e-9
        ):
            return np.asarray(np.degrees(q), dtype=float)
        return None

    def _analytic_candidates(self, flange_pose: FloatArray) -> list[FloatArray]:
        """Closed-form solutions for the nominal A465 structure (spherical wrist), in deg.

        Uses the table's lengths (d1, a(2), d4, d6) and its theta offsets; small deviations of a
        calibrated table from that structure are removed afterwards by :meth:`_refine`.
        """
        d1, L2, L3, d6 = self._d[0], self._a[2], self._d[3], self._d[5]
        off = self._offset
        local = np.linalg.solve(self.base, flange_pose)
        p, R = local[:3, 3], local[:3, :3]
        wrist = p - d6 * R[:, 2]
        out: list[FloatArray] = []
        r_xy = math.hypot(wrist[0], wrist[1])
        h = wrist[2] - d1
        # The nominal geometry: upper arm vertical at q2 = 0, leaning forward with +q2; forearm
        # vertical at q3 = 0, forward with +q3 (offsets -90, -90 in the table).
        base_q1 = math.atan2(wrist[1], wrist[0]) if r_xy > 1e-9 else 0.0
        for q1, r in ((base_q1, r_xy), (base_q1 + math.pi, -r_xy)):
            D = (r * r + h * h - L2 * L2 - L3 * L3) / (2.0 * L2 * L3)
            if abs(D) > 1.0 + 1e-12:
                continue
            D = max(-1.0, min(1.0, D))
            for q3 in (math.acos(D), -math.acos(D)):
                q2 = math.atan2(r, h) - math.atan2(L3 * math.sin(q3), L2 + L3 * math.cos(q3))
                nominal = np.array([q1, q2, q3]) + np.array([0.0, -math.pi / 2, -math.pi / 2]) - off[:3]
                q123 = np.degrees(nominal)
                R03 = self.link_frames(np.concatenate([q123, np.zeros(3)]))[2, :3, :3]
                R03 = np.asarray(np.linalg.solve(self.base[:3, :3], R03), dtype=float)
                M = rot_x(self._alpha[3]).T @ R03.T @ R
                for sign in (1.0, -1.0):
                    cb = max(-1.0, min(1.0, M[2, 2]))
                    sb = sign * math.sqrt(max(0.0, 1.0 - cb * cb))
                    b = math.atan2(sb, cb)
                    if abs(sb) > 1e-9:
                        a = math.atan2(M[1, 2] / sb, M[0, 2] / sb)
                        c = math.atan2(M[2, 1] / sb, -M[2, 0] / sb)
                    else:  # wrist singular: only a + c matters; keep joint 4 at its offset
                        a = 0.0
                        c = math.atan2(M[1, 0], M[0, 0])
                    theta456 = np.array([a, -b, c])
                    q456 = np.degrees(_wrap_rad(theta456 - off[3:]))
                    out.append(np.concatenate([q123, q456]))
        return out

    def inverse_all(self, pose: npt.ArrayLike, *, tool: bool = True) -> list[FloatArray]:
        """Every distinct joint solution (deg) within the limits that reaches ``pose`` (4x4, mm)."""
        target = self._checked_transform(pose, "pose")
        flange_pose = target @ np.linalg.inv(self.tool) if tool else target
        solutions: list[FloatArray] = []
        for candidate in self._analytic_candidates(flange_pose):
            q = self._refine(candidate, flange_pose, tool=False)
            if q is None:
                continue
            q = np.degrees(_wrap_rad(np.radians(q)))
            if not self.within_limits(q):
                continue
            if any(np.allclose(q, s, atol=1e-6) for s in solutions):
                continue
            solutions.append(q)
        return solutions

    def inverse(
        self, pose: npt.ArrayLike, *, seed_deg: npt.ArrayLike | None = None, tool: bool = True
    ) -> FloatArray:
        """The joint solution (deg) within the limits nearest to ``seed_deg`` that reaches ``pose``.

        Parameters
        ----------
        pose
            4x4 target of the tool (``tool=True``) or of the flange, in the world frame (mm).
        seed_deg
            Joints to stay near (usually the current ones); all zeros by default.
        tool
            Whether ``pose`` is the tool's (camera's) pose or the flange's.

        Raises
        ------
        UnreachableError
            No solution within the joint limits.
        """
        seed = np.zeros(JOINTS) if seed_deg is None else self._as_joints(seed_deg)
        solutions = self.inverse_all(pose, tool=tool)
        if not solutions:
            raise UnreachableError("no joint solution within the joint limits reaches this pose")
        return min(solutions, key=lambda s: float(np.max(np.abs(s - seed))))

    @property
    def reach_mm(self) -> float:
        """Distance from the shoulder to the flange with the arm stretched (a(2) + d4 + d6)."""
        return float(self._a[2] + self._d[3] + self._d[5])


__all__ = [
    "A465_DH",
    "A465_JOINT_LIMITS_DEG",
    "LOOK_DOWN",
    "DHRow",
    "Kinematics",
    "KinematicsError",
    "UnreachableError",
    "pose_from_world_row",
    "rot_x",
    "rot_y",
    "rot_z",
    "square_on",
    "transform",
    "world_row",
]
