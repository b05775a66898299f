"""The calibration model: named errors relative to nominal, and the vectorised forward model.

Parameters (natural units: mm and deg; the vector holds *errors*, value = nominal + error):

* per modified DH row i = 1..6 (``DHRow`` index i-1, holding ``alpha(i-1)``, ``a(i-1)``, ``d(i)`` and
  joint i's zero): ``alpha{i-1}``, ``a{i-1}``, ``d{i}``, ``theta{i}_offset``;
* ``beta2``: Hayati's rotation about y on the row between the nominally parallel axes 2 and 3 (index 2);
* the tool (camera in the flange frame): ``tool_x, tool_y, tool_z`` (mm, flange axes) and ``tool_rx,
  tool_ry, tool_rz`` (deg, small rotations about the camera's own axes: ``R = R_nominal Rx Ry Rz``);
* per artifact placement k: ``artifact{k}_x, _y, _z`` (the crossing, base frame, mm) and
  ``artifact{k}_rx, _ry`` (deg: the plane's normal is ``Rx(rx) Ry(ry) n_nominal``; the yaw about the
  normal is not seen by point measurements and is not a parameter);
* per ruler r: ``ruler{r}_x, _y, _z`` (graduation 0 on its axis, base frame, mm) and ``ruler{r}_rx,
  _ry, _rz`` (deg: small rotations about the ruler's own axes ``s, t, n``: ``R = R_taught Rx Ry Rz``;
  the yaw ``rz`` is seen, since a ruler reads along itself);
* with ``camera=True``: ``px_per_mm``, the image scale (magnification) at the plane where the
  captures are taken (where the sensor reads what it reads there in the nominal model: the pinhole's
  depth ``working_distance + sensor_z``), px/mm; and ``sensor_z``, the sensor mount's offset along
  the optical axis (mm; ``sensor_mount[2, 3]``). The pinhole's focal length is then
  ``px_per_mm x (working_distance + sensor_z error)``: a shift of the sensor along the axis with the
  tool's ``z`` the other way leaves every capture at that depth unchanged, so ``sensor_z`` needs
  captures at other depths (a ruler's frames off focus), and ``px_per_mm`` does not.

Forward model for observation j at joints q_j seeing placement k: camera pose ``C = F(q_j) @ tool``;
the crossing ``p_k`` in the camera frame projects through the pinhole to the predicted pixel; the
sensor's ray (origin ``C @ mount @ 0``, direction ``C @ mount @ e_z``) meets the plane
``(p_k, n_k)`` at the predicted reading. A ruler's frame predicts ``(s, t)`` under its reference pixel,
the image scale there and the reading (``_ruler_model``). Residuals are in mm (pixel residuals times
``working_distance / focal_px``; a ruler's ``s`` and ``t`` as they are), the scale's relative, each
divided by its stated sigma.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from station.calibration._names import (
    ANGLE_UNIT_DEG,
    CAMERA_NAMES,
    HAYATI_ROW,
    SCALE_UNIT,
    TOOL_NAMES,
    Sigmas,
    artifact_names,
    dh_names,
    ruler_names,
)
from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    CameraModel,
    FloatArray,
    ObservationArrays,
)
from station.calibration._ruler_model import predict_rulers, small_rotations
from station.calibration._ruler_observations import RulerArrays
from station.kinematics import JOINTS, DHRow, Kinematics, rot_x, rot_y, rot_z, transform


class CalibrationModel:
    """The parameter space and forward model of one calibration setup.

    ``delta`` vectors hold the errors in natural units (mm, deg, px/mm) in the order of :attr:`names`:
    the DH rows, the tool, the artifacts (``placements``), the rulers (``rulers``) and, with ``camera``,
    the camera's scale and the sensor's offset along the optical axis.
    """

    def __init__(
        self,
        setup: CalibrationSetup,
        *,
        placements: Sequence[int] | None = None,
        rulers: Sequence[int] | None = None,
        camera: bool = False,
    ) -> None:
        self.setup = setup
        self.placements: tuple[int, ...] = (
            setup.placements if placements is None else tuple(sorted(placements))
        )
        self.rulers: tuple[int, ...] = tuple(sorted(setup.rulers if rulers is None else rulers))
        self.camera_free = camera
        missing = sorted(set(self.placements) - set(setup.placements))
        if missing:
            raise CalibrationError(f"placements {missing} are not in the setup's artifacts")
        unknown = sorted(set(self.rulers) - set(setup.rulers))
        if unknown:
            raise CalibrationError(
                f"rulers {unknown} are not in the setup's rulers: add their taught placements to"
                " CalibrationSetup.rulers"
            )
        names = dh_names() + list(TOOL_NAMES)
        for k in self.placements:
            names += artifact_names(k)
        for ruler in self.rulers:
            names += ruler_names(ruler)
        if camera:
            names += list(CAMERA_NAMES)
        self.names: tuple[str, ...] = tuple(names)
        self.index = {n: i for i, n in enumerate(self.names)}
        units = []
        for n in self.names:
            is_angle = n.startswith(("alpha", "theta", "beta")) or n.endswith(("_rx", "_ry", "_rz"))
            units.append("deg" if is_angle else "px/mm" if n == "px_per_mm" else "mm")
        self.units: tuple[str, ...] = tuple(units)
        unit_size = {"deg": ANGLE_UNIT_DEG, "px/mm": SCALE_UNIT, "mm": 1.0}
        self.internal_unit = np.array([unit_size[u] for u in self.units])
        """Natural units per internal unit (mm per mm, deg per mrad, px/mm per 0.1 px/mm)."""
        nominal: list[float] = []
        for r in setup.nominal_dh:
            nominal += [r.alpha_deg, r.a_mm, r.d_mm, r.theta_offset_deg]
        nominal.append(setup.nominal_dh[HAYATI_ROW].beta_deg)
        nominal += [*setup.nominal_tool[:3, 3].tolist(), 0.0, 0.0, 0.0]
        for k in self.placements:
            nominal += [*setup.artifacts[k], 0.0, 0.0]
        for ruler in self.rulers:
            nominal += [*setup.rulers[ruler].origin_mm, 0.0, 0.0, 0.0]
        if camera:
            nominal += [self.nominal_px_per_mm, float(setup.sensor_mount[2, 3])]
        self.nominal = np.array(nominal, dtype=float)
        """Nominal values (natural units): the DH values, the tool's translation, the artifacts' and the
        rulers' positions, the camera's scale and the sensor's offset."""
        self._normals0 = np.stack([setup.normal(k) for k in self.placements]) if self.placements else None
        self._ruler_frames0 = (
            np.stack([setup.rulers[k].frame() for k in self.rulers]) if self.rulers else np.zeros((0, 3, 3))
        )
        self._n_dh = 4 * JOINTS + 1
        self._tool_slice = slice(self._n_dh, self._n_dh + 6)
        self._artifact_start = self._n_dh + 6
        self._ruler_start = self._artifact_start + 5 * len(self.placements)
        self._camera_start = self._ruler_start + 6 * len(self.rulers)

    @property
    def size(self) -> int:
        return len(self.names)

    @property
    def nominal_px_per_mm(self) -> float:
        """The image scale the setup's camera gives at its working distance (px/mm)."""
        cam = self.setup.camera
        return cam.focal_px / cam.working_distance_mm

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

    def sensor_z_error(self, delta: npt.ArrayLike) -> float:
        """The sensor's offset along the optical axis, minus the setup's (mm; 0 without ``camera``)."""
        return float(self._check(delta)[self.index["sensor_z"]]) if self.camera_free else 0.0

    def px_per_mm(self, delta: npt.ArrayLike) -> float:
        """The image scale at the capture plane (px/mm)."""
        if not self.camera_free:
            return self.nominal_px_per_mm
        return float(self.nominal_px_per_mm + self._check(delta)[self.index["px_per_mm"]])

    def focal_px(self, delta: npt.ArrayLike) -> float:
        """The pinhole's focal length (px): the scale times the capture plane's depth."""
        if not self.camera_free:
            return self.setup.camera.focal_px
        return self.px_per_mm(delta) * (self.setup.camera.working_distance_mm + self.sensor_z_error(delta))

    def camera(self, delta: npt.ArrayLike) -> CameraModel:
        """The camera of these errors (the setup's when the camera is not a parameter)."""
        if not self.camera_free:
            return self.setup.camera
        cam = self.setup.camera
        depth = cam.working_distance_mm + self.sensor_z_error(delta)
        return CameraModel(self.focal_px(delta), cam.principal_px, cam.width, cam.height, depth)

    def sensor_mount(self, delta: npt.ArrayLike) -> FloatArray:
        """The sensor's 4x4 pose in the camera frame, its offset along the optical axis fitted."""
        mount = self.setup.sensor_mount.copy()
        mount[2, 3] += self.sensor_z_error(delta)
        return mount

    def artifacts(self, delta: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Crossing positions (K, 3) and unit plane normals (K, 3), base frame."""
        d = self._check(delta)
        block = (self.nominal + d)[self._artifact_start : self._ruler_start].reshape(-1, 5)
        if self._normals0 is None:
            return np.zeros((0, 3)), np.zeros((0, 3))
        rx, ry = np.radians(block[:, 3]), np.radians(block[:, 4])
        n0 = self._normals0
        # Rx(rx) @ Ry(ry) @ n0, vectorised
        cy, sy = np.cos(ry), np.sin(ry)
        t = np.stack([cy * n0[:, 0] + sy * n0[:, 2], n0[:, 1], -sy * n0[:, 0] + cy * n0[:, 2]], axis=1)
        cx, sx = np.cos(rx), np.sin(rx)
        n = np.stack([t[:, 0], cx * t[:, 1] - sx * t[:, 2], sx * t[:, 1] + cx * t[:, 2]], axis=1)
        return block[:, :3].copy(), n

    def ruler_frames(self, delta: npt.ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Each ruler's origin (R, 3) and rotation (R, 3, 3; columns ``s, t, n``), base frame."""
        d = self._check(delta)
        block = (self.nominal + d)[self._ruler_start : self._camera_start].reshape(-1, 6)
        rotations = self._ruler_frames0 @ small_rotations(np.radians(block[:, 3:]))
        return block[:, :3].copy(), rotations

    def artifact_delta_indices(self, k_index: int) -> list[int]:
        """Indices of placement ``placements[k_index]``'s five parameters."""
        s = self._artifact_start + 5 * k_index
        return list(range(s, s + 5))

    def ruler_delta_indices(self, r_index: int) -> list[int]:
        """Indices of ruler ``rulers[r_index]``'s six parameters."""
        s = self._ruler_start + 6 * r_index
        return list(range(s, s + 6))

    def artifact_indices(self) -> list[int]:
        """The artifacts' parameters (the crossings' placements)."""
        return list(range(self._artifact_start, self._ruler_start))

    def placement_indices(self) -> list[int]:
        """Everything placed in the cell: the artifacts' and the rulers' parameters."""
        return list(range(self._artifact_start, self._camera_start))

    def camera_indices(self) -> list[int]:
        """The camera's scale and the sensor's offset (none without ``camera``)."""
        return list(range(self._camera_start, self.size))

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
        focal = self.focal_px(delta)
        with np.errstate(divide="ignore", invalid="ignore"):
            px = np.column_stack(
                [
                    cam.principal_px[0] + focal * pc[:, 0] / pc[:, 2],
                    cam.principal_px[1] + focal * pc[:, 1] / pc[:, 2],
                ]
            )
        mount = self.sensor_mount(delta)
        origin = np.einsum("nij,j->ni", R, mount[:3, 3]) + t
        beam = np.einsum("nij,j->ni", R, mount[:3, 2])
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.einsum("ni,ni->n", n, p - origin) / np.einsum("ni,ni->n", n, beam)
        return px, z

    def predict(self, delta: npt.ArrayLike, arrays: ObservationArrays) -> tuple[FloatArray, FloatArray]:
        """Predicted pixels (N, 2) and sensor readings (N,) (mm) of the observations."""
        return self.project(delta, self.camera_poses(delta, arrays.joints_deg), arrays)

    def predict_rulers(
        self, delta: npt.ArrayLike, rulers: RulerArrays, cameras: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Predicted ``(s, t)`` (R, 2) mm, image scale (R,) px/mm and reading (R,) mm of ruler frames."""
        if cameras is None:
            cameras = self.camera_poses(delta, rulers.joints_deg)
        origins, rotations = self.ruler_frames(delta)
        return predict_rulers(
            cameras,
            origins[rulers.ruler_index],
            rotations[rulers.ruler_index],
            rulers.reference_px,
            focal_px=self.focal_px(delta),
            principal_px=self.setup.camera.principal_px,
            mount=self.sensor_mount(delta),
        )

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

    def ruler_residuals(
        self, delta: npt.ArrayLike, rulers: RulerArrays, cameras: FloatArray | None = None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Measured minus predicted of ruler frames: ``(s, t)`` (R, 2) mm, the scale (S,) relative (measured
        over predicted, minus 1) where measured, the reading (Z,) mm where there is one."""
        st, scale, z = self.predict_rulers(delta, rulers, cameras)
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = (rulers.scale / scale - 1.0)[rulers.has_scale]
        return rulers.st_mm - st, rel, (rulers.z_mm - z)[rulers.has_z]

    def weighted_residuals(
        self,
        delta: npt.ArrayLike,
        arrays: ObservationArrays,
        sigmas: Sigmas,
        cameras: FloatArray | None = None,
        *,
        rulers: RulerArrays | None = None,
        ruler_cameras: FloatArray | None = None,
    ) -> FloatArray:
        """The residual vector the fit minimises, dimensionless: ``[xy / sigma_xy (2N), z / sigma_z (M)]``
        and, with ``rulers``, ``[st / sigma_ruler (2R), scale / sigma_scale (S), z / sigma_z (Z)]``."""
        xy, dz = self.residuals_mm(delta, arrays, cameras)
        parts = [xy.ravel() / sigmas.xy_mm, dz / sigmas.z_mm]
        if rulers is not None and len(rulers):
            st, rel, rz = self.ruler_residuals(delta, rulers, ruler_cameras)
            parts += [st.ravel() / sigmas.ruler_mm, rel / sigmas.scale_rel, rz / sigmas.z_mm]
        r = np.concatenate(parts)
        return np.where(np.isfinite(r), r, 1e6)

    def jacobian(
        self,
        delta: npt.ArrayLike,
        arrays: ObservationArrays,
        sigmas: Sigmas,
        free: Sequence[int] | None = None,
        *,
        rulers: RulerArrays | None = None,
    ) -> FloatArray:
        """d(weighted residuals) / d(errors in internal units) by central differences, columns ``free``.

        Internal units: mm, mrad (:data:`ANGLE_UNIT_DEG`) and 0.1 px/mm. The artifacts', rulers' and
        camera's columns reuse the camera poses.
        """
        d0 = self._check(delta)
        cols = list(range(self.size)) if free is None else list(free)
        h = 1e-3  # internal units: 1 um, 1 urad, 1e-4 px/mm
        cameras = self.camera_poses(d0, arrays.joints_deg)
        ruler_cameras = None if rulers is None else self.camera_poses(d0, rulers.joints_deg)
        rows = 2 * len(arrays) + int(arrays.has_z.sum()) + (0 if rulers is None else rulers.residual_count)
        out = np.empty((rows, len(cols)))
        for c, i in enumerate(cols):
            step = np.zeros(self.size)
            step[i] = h * self.internal_unit[i]
            plus, minus = d0 + step, d0 - step
            if i >= self._artifact_start:
                rp = self.weighted_residuals(
                    plus, arrays, sigmas, cameras, rulers=rulers, ruler_cameras=ruler_cameras
                )
                rm = self.weighted_residuals(
                    minus, arrays, sigmas, cameras, rulers=rulers, ruler_cameras=ruler_cameras
                )
            else:
                rp = self.weighted_residuals(plus, arrays, sigmas, rulers=rulers)
                rm = self.weighted_residuals(minus, arrays, sigmas, rulers=rulers)
            out[:, c] = (rp - rm) / (2 * h)
        return out


__all__ = [
    "ANGLE_UNIT_DEG",
    "CAMERA_NAMES",
    "HAYATI_ROW",
    "TOOL_NAMES",
    "CalibrationModel",
    "Sigmas",
    "artifact_names",
    "dh_names",
    "ruler_names",
]
