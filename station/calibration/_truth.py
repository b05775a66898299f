"""A known true arm expressed in the identified parameterisation (for tests and benchmarks).

The fit leaves the structural parameters at nominal; the truth they carry moves elsewhere:

* the base row's errors (``alpha0, a0, d1, theta1_offset``) are a fixed rigid transform ``G`` of the
  whole arm (``T01_true(q1) = G T01_model(q1)`` for every q1, since ``RotZ(theta1)`` and ``TransZ(d1)``
  commute): the artifacts, seen in the model's base frame, are ``G^-1`` of their true poses;
* ``d6`` and ``theta6_offset`` are ``RotZ(dtheta6) TransZ(dd6)`` in front of the tool;
* ``d3`` is added to ``d2`` (exact when axes 2 and 3 are parallel; with the true ``alpha2`` and
  ``beta2`` the difference is of second order, ``d3 x angle``: below 1 um for 0.5 mm and 0.1 deg).

The rulers, like the artifacts, are seen through ``G^-1``; the camera's scale and the sensor's offset
(when the model fits them) are the true camera's: its focal length over the capture plane's true depth.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt

from station.calibration._identifiability import reported_name
from station.calibration._model import HAYATI_ROW, CalibrationModel
from station.calibration._observations import FloatArray
from station.calibration._start import rotation_angles
from station.kinematics import JOINTS, DHRow, Kinematics, rot_z, transform


def _t01(row: DHRow) -> FloatArray:
    return Kinematics([row, *([DHRow(0.0, 0.0, 0.0)] * (JOINTS - 1))]).flange(np.zeros(JOINTS))


def equivalent_errors(
    model: CalibrationModel,
    true_dh: Sequence[DHRow],
    true_tool: npt.ArrayLike,
    true_artifacts: Mapping[int, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    true_rulers: Mapping[int, npt.ArrayLike] | None = None,
    true_camera: tuple[float, float] | None = None,
) -> FloatArray:
    """The error vector of ``model`` that describes the true arm with the structural parameters at nominal.

    Parameters
    ----------
    true_dh, true_tool
        The true DH table and camera-in-flange transform (4x4).
    true_artifacts
        Per placement: the true crossing (base frame, mm) and the plane's normal (either sign).
    true_rulers
        Per ruler of the model: its true 4x4 frame (origin at graduation 0, columns ``s, t, n``).
    true_camera
        When the model fits the camera: the true focal length (px) and sensor offset along the optical
        axis (``sensor_mount[2, 3]``, mm).
    """
    nominal_dh = model.setup.nominal_dh
    delta = model.zeros()
    for i, (t, n) in enumerate(zip(true_dh, nominal_dh, strict=True)):
        base = 4 * i
        delta[base : base + 4] = [
            t.alpha_deg - n.alpha_deg,
            t.a_mm - n.a_mm,
            t.d_mm - n.d_mm,
            t.theta_offset_deg - n.theta_offset_deg,
        ]
    delta[4 * JOINTS] = true_dh[HAYATI_ROW].beta_deg - nominal_dh[HAYATI_ROW].beta_deg
    # base row -> G applied to the artifacts
    G = _t01(true_dh[0]) @ np.linalg.inv(_t01(nominal_dh[0]))
    Ginv = np.linalg.inv(G)
    for name in ("alpha0", "a0", "d1", "theta1_offset"):
        delta[model.index[name]] = 0.0
    # d3 into d2
    delta[model.index["d2"]] += delta[model.index["d3"]]
    delta[model.index["d3"]] = 0.0
    # d6, theta6 into the tool
    d6, th6 = delta[model.index["d6"]], delta[model.index["theta6_offset"]]
    delta[model.index["d6"]] = delta[model.index["theta6_offset"]] = 0.0
    tool = transform(rot_z(math.radians(th6)), (0.0, 0.0, d6)) @ np.asarray(true_tool, dtype=float)
    R = model.setup.nominal_tool[:3, :3].T @ tool[:3, :3]
    ry = math.asin(max(-1.0, min(1.0, float(R[0, 2]))))
    rx = math.atan2(-float(R[1, 2]), float(R[2, 2]))
    rz = math.atan2(-float(R[0, 1]), float(R[0, 0]))
    start = model.index["tool_x"]
    delta[start : start + 3] = tool[:3, 3] - model.setup.nominal_tool[:3, 3]
    delta[start + 3 : start + 6] = np.degrees([rx, ry, rz])
    for k_index, k in enumerate(model.placements):
        point, normal = true_artifacts[k]
        p = Ginv[:3, :3] @ np.asarray(point, dtype=float) + Ginv[:3, 3]
        nt = Ginv[:3, :3] @ np.asarray(normal, dtype=float)
        n0 = model.setup.normal(k)
        nt = nt if nt @ n0 >= 0 else -nt
        rx_k, ry_k = _tilt_angles(n0, nt / np.linalg.norm(nt))
        idx = model.artifact_delta_indices(k_index)
        delta[idx[:3]] = p - np.asarray(model.setup.artifacts[k], dtype=float)
        delta[idx[3:]] = np.degrees([rx_k, ry_k])
    for r_index, r in enumerate(model.rulers):
        if true_rulers is None or r not in true_rulers:
            raise ValueError(f"the model has ruler {r}: give its true frame in true_rulers")
        T = Ginv @ np.asarray(true_rulers[r], dtype=float)
        idx = model.ruler_delta_indices(r_index)
        delta[idx[:3]] = T[:3, 3] - np.asarray(model.setup.rulers[r].origin_mm, dtype=float)
        delta[idx[3:]] = np.degrees(rotation_angles(model.setup.rulers[r].frame().T @ T[:3, :3]))
    if model.camera_free:
        if true_camera is None:
            raise ValueError("the model fits the camera: give true_camera (focal length px, sensor z mm)")
        focal, sensor_z = true_camera
        sensor_error = sensor_z - float(model.setup.sensor_mount[2, 3])
        delta[model.index["sensor_z"]] = sensor_error
        scale = focal / (model.setup.camera.working_distance_mm + sensor_error)
        delta[model.index["px_per_mm"]] = scale - model.nominal_px_per_mm
    return delta


def _tilt_angles(n0: FloatArray, n: FloatArray) -> tuple[float, float]:
    """The smallest (rx, ry) (rad) with ``Rx(rx) Ry(ry) n0 = n`` (unit vectors)."""
    # Ry keeps the y component: (Rx(-rx) n)_y = cos(rx) n_y + sin(rx) n_z must equal n0_y
    amplitude = math.hypot(float(n[1]), float(n[2]))
    phase = math.atan2(float(n[2]), float(n[1]))
    spread = math.acos(max(-1.0, min(1.0, float(n0[1]) / amplitude)))
    rx = min((phase + spread, phase - spread), key=lambda a: abs(math.remainder(a, 2 * math.pi)))
    rx = math.remainder(rx, 2 * math.pi)
    c, s = math.cos(-rx), math.sin(-rx)
    w = np.array([n[0], c * n[1] - s * n[2], s * n[1] + c * n[2]])
    ry = math.atan2(float(w[0]), float(w[2])) - math.atan2(float(n0[0]), float(n0[2]))
    return rx, math.remainder(ry, 2 * math.pi)


def true_values(
    model: CalibrationModel,
    true_dh: Sequence[DHRow],
    true_tool: npt.ArrayLike,
    true_artifacts: Mapping[int, tuple[npt.ArrayLike, npt.ArrayLike]],
    *,
    true_rulers: Mapping[int, npt.ArrayLike] | None = None,
    true_camera: tuple[float, float] | None = None,
) -> dict[str, float]:
    """A known true arm's value of every parameter, by reported name (natural units, ``d2+d3`` as the
    sum): what an identification's estimates are compared with in tests and benchmarks (the rulers and
    the camera as :func:`equivalent_errors` takes them)."""
    delta = equivalent_errors(
        model, true_dh, true_tool, true_artifacts, true_rulers=true_rulers, true_camera=true_camera
    )
    values = model.nominal + delta
    values[model.index["d2"]] += model.nominal[model.index["d3"]]
    return {reported_name(n) if n == "d2" else n: float(v) for n, v in zip(model.names, values, strict=True)}


__all__ = ["equivalent_errors", "true_values"]
