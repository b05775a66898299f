"""The calibration model: named errors relative to nominal, and the vectorised forward model.

Parameters (natural units: mm and deg; the vector holds *errors*, value = nominal + error):

* per modified DH row i = 1..6 (``DHRow`` index i-1, holding ``alpha(i-1)``, ``a(i-1)``, ``d(i)`` and
  joint i's zero): ``alpha{i-1}``, ``a{i-1}``, ``d{i}``, ``theta{i}_offset``;
* ``beta2``: Hayati's rotation about y on the row between the nominally parallel axes 2 and 3 (index 2);
* the tool (camera in the flange frame): ``tool_x, tool_y, tool_z`` (mm, flange axes) and ``tool_rx,
  tool_ry, tool_rz`` (deg, small rotations about the camera's own axes: ``R = R_nominal Rx Ry Rz``);
* per artifact placement k: ``artifact{k}_x, _y, _z`` (the crossing, base frame, mm) and
  ``artifact{k}_rx, _ry`` (deg: the plane's normal is ``Rx(rx) Ry(ry) n_nominal``; the yaw about the
  normal is not seen by point measurements and is not a parameter).

Forward model for observation j at joints q_j seeing placement k: camera pose ``C = F(q_j) @ tool``;
the crossing ``p_k`` in the camera frame projects through the pinhole to the predicted pixel; the
sensor's ray (origin ``C @ mount @ 0``, direction ``C @ mount @ e_z``) meets the plane
``(p_k, n_k)`` at the predicted reading. Residuals are in mm (pixel residuals times
``working_distance / focal_px``), divided by the stated sigmas.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    FloatArray,
    ObservationArrays,
)
from station.kinematics import JOINTS, DHRow, Kinematics, rot_x, rot_y, rot_z, transform

ANGLE_UNIT_DEG = math.degrees(1e-3)
"""Internal unit of angles: 1 mrad (so that 1 internal unit of an angle moves a 1 m lever by 1 mm)."""

DH_FIELDS = ("alpha", "a", "d", "theta")
TOOL_NAMES = ("tool_x", "tool_y", "tool_z", "tool_rx", "tool_ry", "tool_rz")
ARTIFACT_FIELDS = ("x", "y", "z", "rx", "ry")
HAYATI_ROW = 2
"""DH row index (0-based) carrying ``beta2``: the link between the nominally parallel axes 2 and 3."""


def dh_names() -> list[str]:
    """The 24 DH parameter names in row order, then ``beta2``."""
    names: list[str] = []
    for i in range(1, JOINTS + 1):
        names += [f"alpha{i - 1}", f"a{i - 1}", f"d{i}", f"theta{i}_offset"]
    return [*names, f"beta{HAYATI_ROW}"]


def artifact_names(placement: int) -> list[str]:
    """The five parameter names of one artifact placement."""
    return [f"artifact{placement}_{f}" for f in ARTIFACT_FIELDS]


@dataclass(frozen=True)
class Sigmas:
    """The measurement's standard deviations (mm) that weight the residuals.

    ``xy_mm``: the crossing's position in the image, at the focal plane (a pixel times the scale);
    ``z_mm``: the distance sensor's reading. Both should include the arm's repeatability, which moves
    the camera between captures as much as the measurement's own noise does.
    """

    xy_mm: float = 0.005
    z_mm: float = 0.005

    def __post_init__(self) -> None:
        if not (self.xy_mm > 0 and self.z_mm > 0):
            raise CalibrationError(f"sigmas must be > 0 mm, got xy_mm={self.xy_mm!r}, z_mm={self.z_mm!r}")


class CalibrationModel:
    """The parameter space and forward model of one calibration setup.

    ``delta`` vectors hold the errors in natural units (mm, deg) in the order of :attr:`names`.
    """

    def __init__(self, setup: CalibrationSetup, *, placements: Sequence[int] | None = None) -> None:
        self.setup = setup
        self.placements: tuple[int, ...] = (
            setup.placements if placements is None else tuple(sorted(placements))
        )
        missing = sorted(set(self.placements) - set(setup.placements))
        if missing:
            raise CalibrationError(f"placements {missing} are not in the setup's artifacts")
        names = dh_names() + list(TOOL_NAMES)
        for k in self.placements:
            names += artifact_names(k)
        self.names: tuple[str, ...] = tuple(names)
        self.index = {n: i for i, n in enumerate(self.names)}
        units = []
        for n in self.names:
            is_angle = n.startswith(("alpha", "theta", "beta")) or n.endswith(("_rx", "_ry", "_rz"))
            units.append("deg" if is_angle else "mm")
        self.units: tuple[str, ...] = tuple(units)
        self.internal_unit = np.array([ANGLE_UNIT_DEG if u == "deg" else 1.0 for u in self.units])
        """Natural units per internal unit (mm per mm, deg per mrad)."""
        nominal: list[float] = []
        for r in setup.nominal_dh:
            nominal += [r.alpha_deg, r.a_mm, r.d_mm, r.theta_offset_deg]
        nominal.append(setup.nominal_dh[HAYATI_ROW].beta_deg)
        nominal += [*setup.nominal_tool[:3, 3].tolist(), 0.0, 0.0, 0.0]
        for k in self.placements:
            nominal += [*setup.artifacts[k], 0.0, 0.0]
        self.nominal = np.array(nominal, dtype=float)
        """Nominal values (natural units): the DH values, the tool's translation, the artifacts' positions."""
        self._normals0 = np.stack([setup.normal(k) for k in self.placements])
        self._n_dh = 4 * JOINTS + 1
        self._tool_slice = slice(self._n_dh, self._n_dh + 6)
        self._artifact_start = self._n_dh + 6

    @property
    def size(self) -> int:
        return len(self.names)

    def zeros(self) -> FloatArray:
        return np.zeros(self.size)

    def _check(self, delta: npt.ArrayLike) -> FloatArray:
        d = np.asarray(delta, dtype=float)
        if d.shape != (self.size,):
            raise CalibrationError(
                f"a parameter vector has {self.size} errors ({self.names[0]}...), got {d.shape}"
            )
        return d

    # ---------------------------------------------------------------- model parts

    def dh(self, delta: npt.ArrayLike) -> tuple[DHRow, ...]:
        """The DH table of these errors."""
        d = self._check(delta)
        values = self.nominal[: 4 * JOINTS] + d[: 4 * JOINTS]
        beta = self.nominal[4 * JOINTS] + d[4 * JOINTS]
        rows = []
        for i in range(JOINTS):
            alpha, a, dd, theta = (float(v) for v in values[4 * i : 4 * i + 4])
            b = float(beta) if i == HAYATI_ROW else self.setup.nominal_dh[i].beta_deg
            rows.append(DHRow(alpha_deg=alpha, a_mm=a, d_mm=dd, theta_offset_deg=theta, beta_deg=b))
        return tuple(rows)

    def tool(self, delta: npt.ArrayLike) -> FloatArray:
        """Camera in the flange frame (4x4): translation nominal + (x, y, z); rotation R_nom Rx Ry Rz."""
        d = self._check(delta)[self._tool_slice]
        rx, ry, rz = np.radians(d[3:])
        R = self.setup.nominal_tool[:3, :3] @ rot_x(rx) @ rot_y(ry) @ rot_z(rz)
        return transform(R, self.setup.nominal_tool[:3, 3] + d[:3])

    def kinematics(self, delta: npt.ArrayLike) -> Kinematics:
        """The arm of these errors with the camera as the tool."""
        return Kinematics(self.dh(delta), tool=self.tool(delta))

    def artifacts(self, delta: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Crossing positions (K, 3) and unit plane normals (K, 3), base frame."""
        d = self._check(delta)
        block = (self.nominal + d)[self._artifact_start :].reshape(-1, 5)
        rx, ry = np.radians(block[:, 3]), np.radians(block[:, 4])
        n0 = self._normals0
        # Rx(rx) @ Ry(ry) @ n0, vectorised
        cy, sy = np.cos(ry), np.sin(ry)
        t = np.stack([cy * n0[:, 0] + sy * n0[:, 2], n0[:, 1], -sy * n0[:, 0] + cy * n0[:, 2]], axis=1)
        cx, sx = np.cos(rx), np.sin(rx)
        n = np.stack([t[:, 0], cx * t[:, 1] - sx * t[:, 2], sx * t[:, 1] + cx * t[:, 2]], axis=1)
        return block[:, :3].copy(), n

    def artifact_delta_indices(self, k_index: int) -> list[int]:
        """Indices of placement ``placements[k_index]``'s five parameters."""
        s = self._artifact_start + 5 * k_index
        return list(range(s, s + 5))

    def artifact_indices(self) -> list[int]:
        return list(range(self._artifact_start, self.size))

    # ---------------------------------------------------------------- forward model

    def camera_poses(self, delta: npt.ArrayLike, joints_deg: FloatArray) -> FloatArray:
        """Camera poses (N, 4, 4) in the base frame."""
        return self.kinematics(delta).tool_pose(joints_deg)

    def project(
        self, delta: npt.ArrayLike, cameras: FloatArray, arrays: ObservationArrays
    ) -> tuple[FloatArray, FloatArray]:
        """Predicted pixels (N, 2) and sensor readings (N,) for given camera poses (N, 4, 4)."""
        points, normals = self.artifacts(delta)
        p = points[arrays.placement_index]
        n = normals[arrays.placement_index]
        R = cameras[:, :3, :3]
        t = cameras[:, :3, 3]
        pc = np.einsum("nji,nj->ni", R, p - t)  # R^T (p - t)
        cam = self.setup.camera
        with np.errstate(divide="ignore", invalid="ignore"):
            px = np.column_stack(
                [
                    cam.principal_px[0] + cam.focal_px * pc[:, 0] / pc[:, 2],
                    cam.principal_px[1] + cam.focal_px * pc[:, 1] / pc[:, 2],
                ]
            )
        mount = self.setup.sensor_mount
        origin = np.einsum("nij,j->ni", R, mount[:3, 3]) + t
        beam = np.einsum("nij,j->ni", R, mount[:3, 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.einsum("ni,ni->n", n, p - origin) / np.einsum("ni,ni->n", n, beam)
        return px, z

    def predict(self, delta: npt.ArrayLike, arrays: ObservationArrays) -> tuple[FloatArray, FloatArray]:
        """Predicted pixels (N, 2) and sensor readings (N,) (mm) of the observations."""
        return self.project(delta, self.camera_poses(delta, arrays.joints_deg), arrays)

    def residuals_mm(
        self, delta: npt.ArrayLike, arrays: ObservationArrays, cameras: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray]:
        """Measured minus predicted: image residuals (N, 2) in mm at the focal plane, z residuals (M,) mm
        for the M observations with a reading."""
        if cameras is None:
            cameras = self.camera_poses(delta, arrays.joints_deg)
        px, z = self.project(delta, cameras, arrays)
        xy = (arrays.center_px - px) * self.setup.camera.mm_per_px
        dz = (arrays.z_mm - z)[arrays.has_z]
        return xy, dz

    def weighted_residuals(
        self,
        delta: npt.ArrayLike,
        arrays: ObservationArrays,
        sigmas: Sigmas,
        cameras: FloatArray | None = None,
    ) -> FloatArray:
        """The residual vector the fit minimises: ``[xy / sigma_xy (2N), z / sigma_z (M)]``, dimensionless."""
        xy, dz = self.residuals_mm(delta, arrays, cameras)
        r = np.concatenate([xy.ravel() / sigmas.xy_mm, dz / sigmas.z_mm])
        return np.where(np.isfinite(r), r, 1e6)

    def jacobian(
        self,
        delta: npt.ArrayLike,
        arrays: ObservationArrays,
        sigmas: Sigmas,
        free: Sequence[int] | None = None,
    ) -> FloatArray:
        """d(weighted residuals) / d(errors in internal units) by central differences, columns ``free``.

        Internal units: mm and mrad (:data:`ANGLE_UNIT_DEG`). Artifact columns reuse the camera poses.
        """
        d0 = self._check(delta)
        cols = list(range(self.size)) if free is None else list(free)
        h = 1e-3  # internal units: 1 um, 1 urad
        cameras = self.camera_poses(d0, arrays.joints_deg)
        out = np.empty((2 * len(arrays) + int(arrays.has_z.sum()), len(cols)))
        for c, i in enumerate(cols):
            step = np.zeros(self.size)
            step[i] = h * self.internal_unit[i]
            plus, minus = d0 + step, d0 - step
            if i >= self._artifact_start:
                rp = self.weighted_residuals(plus, arrays, sigmas, cameras)
                rm = self.weighted_residuals(minus, arrays, sigmas, cameras)
            else:
                rp = self.weighted_residuals(plus, arrays, sigmas)
                rm = self.weighted_residuals(minus, arrays, sigmas)
            out[:, c] = (rp - rm) / (2 * h)
        return out


__all__ = [
    "ANGLE_UNIT_DEG",
    "HAYATI_ROW",
    "TOOL_NAMES",
    "CalibrationModel",
    "Sigmas",
    "artifact_names",
    "dh_names",
]
