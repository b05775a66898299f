"""The absolute positioning error: how well a kinematic model predicts the arm's large motions, read on a
ruler.

Each "pose" frame of a ruler gives, like a crossing's capture (``_metric``), the point under its
reference pixel in the base frame: the model's camera pose at the encoder readings and the pixel's ray,
which meets the ruler's surface where the sensor's reading puts it (the beam's end, on a plane of the
ruler's normal: given, or the mean optical axis of its frames, which look square at it or lean evenly
about that); where the frame has no reading, the point at the capture plane's depth (the camera model's
working distance) along the optical axis. The same point lies on the ruler at the ``(s, t)`` the frame
read. For two frames of one ruler from different configurations, ``s`` at least ``min_separation_mm``
apart, the truth is the ruler's distance ``hypot(ds, dt)``: the pair's error is the model's distance
between its two points minus that (the arm's predicted displacement against the ruler's reading). The
metric is the mean of its magnitude over the pairs.

Where the crossings' relative error (``relative_error_um``) judges a model near each artifact, this one
judges it along the rulers, over their length (10 to 250 mm): lengths, which no relative measurement
of a crossing constrains.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from station.calibration._observations import CalibrationError, CameraModel, FloatArray
from station.calibration._ruler_observations import RulerObservation
from station.kinematics import Kinematics

if TYPE_CHECKING:
    from station.calibration._result import CalibrationResult

MIN_SEPARATION_MM = 10.0
"""Pairs of frames closer than this along the ruler are left out: the relative error covers short moves."""


def _kinematics(model: Kinematics | CalibrationResult) -> Kinematics:
    return model if isinstance(model, Kinematics) else model.kinematics()


def ruler_points(
    observations: Sequence[RulerObservation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
    *,
    plane_normals: Mapping[int, npt.ArrayLike] | None = None,
) -> FloatArray:
    """The point under each frame's reference pixel in the base frame (N, 3, mm), as the module says."""
    if not observations:
        return np.zeros((0, 3))
    mount = np.asarray(sensor_mount, dtype=float)
    q = np.array([o.joints_deg for o in observations], dtype=float)
    ref = np.array([o.reference_px for o in observations], dtype=float)
    C = _kinematics(kinematics).tool_pose(q)
    R, c = C[:, :3, :3], C[:, :3, 3]
    ray = np.column_stack(
        [
            (ref[:, 0] - camera.principal_px[0]) / camera.focal_px,
            (ref[:, 1] - camera.principal_px[1]) / camera.focal_px,
            np.ones(len(ref)),
        ]
    )
    a = np.einsum("nij,nj->ni", R, ray)
    lam = np.full(len(observations), camera.working_distance_mm)  # the capture plane along the axis
    ruler = np.array([o.ruler for o in observations])
    reading = np.array([np.nan if o.z_mm is None else o.z_mm for o in observations])
    for r in np.unique(ruler):
        idx = np.flatnonzero((ruler == r) & np.isfinite(reading))
        if not idx.size:
            continue
        if plane_normals is not None and int(r) in plane_normals:
            n = np.asarray(plane_normals[int(r)], dtype=float)
        else:
            n = R[ruler == r, :, 2].mean(axis=0)
        n = n / np.linalg.norm(n)
        beam_end = np.einsum("nij,j->ni", R[idx], mount[:3, 3]) + c[idx]
        beam_end += reading[idx, None] * np.einsum("nij,j->ni", R[idx], mount[:3, 2])
        lam[idx] = ((beam_end - c[idx]) @ n) / (a[idx] @ n)
    return np.asarray(c + lam[:, None] * a, dtype=float)


def ruler_pair_errors_um(
    observations: Sequence[RulerObservation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
    *,
    min_separation_mm: float = MIN_SEPARATION_MM,
    plane_normals: Mapping[int, npt.ArrayLike] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Every qualifying pair's signed error (um: the model's distance minus the ruler's) and the ruler's
    distance (mm), as the module says. ``kinematics``: the model judged, camera as its tool (or a
    ``CalibrationResult``: its calibrated kinematics); ``camera`` and ``sensor_mount`` to go with it;
    ``plane_normals``: each ruler's surface normal (either sign) in that model's base frame."""
    if not (math.isfinite(min_separation_mm) and min_separation_mm >= 0):
        raise CalibrationError(f"min_separation_mm must be >= 0, got {min_separation_mm!r}")
    used = [o for o in observations if o.kind == "pose"]
    if not used:
        return np.zeros(0), np.zeros(0)
    points = ruler_points(used, kinematics, camera, sensor_mount, plane_normals=plane_normals)
    st = np.array([(o.position_mm, o.offset_mm) for o in used])
    ruler = np.array([o.ruler for o in used])
    config = np.array([o.configuration for o in used])
    errors, lengths = [], []
    for r in np.unique(ruler):
        idx = np.flatnonzero(ruler == r)
        i, j = np.triu_indices(len(idx), k=1)
        a, b = idx[i], idx[j]
        keep = (config[a] != config[b]) & (np.abs(st[a, 0] - st[b, 0]) >= min_separation_mm)
        a, b = a[keep], b[keep]
        read = np.hypot(st[a, 0] - st[b, 0], st[a, 1] - st[b, 1])
        model = np.linalg.norm(points[a] - points[b], axis=1)
        errors.append((model - read) * 1000.0)
        lengths.append(read)
    return np.concatenate(errors), np.concatenate(lengths)


def absolute_error_um(
    observations: Sequence[RulerObservation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
    *,
    min_separation_mm: float = MIN_SEPARATION_MM,
    plane_normals: Mapping[int, npt.ArrayLike] | None = None,
) -> float:
    """The mean magnitude of the pair errors (um) over the frames (see :func:`ruler_pair_errors_um`).

    Raises
    ------
    CalibrationError
        No pair: the frames need two configurations on one ruler at least ``min_separation_mm`` apart.
    """
    errors, _ = ruler_pair_errors_um(
        observations,
        kinematics,
        camera,
        sensor_mount,
        min_separation_mm=min_separation_mm,
        plane_normals=plane_normals,
    )
    if errors.size == 0:
        raise CalibrationError(
            f"no pair of 'pose' frames of one ruler from different configurations {min_separation_mm:g} mm or"
            " more apart: the absolute error needs frames along each ruler"
        )
    return float(np.abs(errors).mean())


def absolute_floor_um(sigma_mm: float) -> float:
    """The absolute error (um) that a point noise of ``sigma_mm`` (each of ``s`` and ``t``, per frame)
    leaves: a pair's error is the difference of two such noises along the pair, of mean magnitude
    ``2 sigma / sqrt(pi)``."""
    return 2.0 * sigma_mm / math.sqrt(math.pi) * 1000.0


__all__ = [
    "MIN_SEPARATION_MM",
    "absolute_error_um",
    "absolute_floor_um",
    "ruler_pair_errors_um",
    "ruler_points",
]
