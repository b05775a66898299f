"""The relative positioning error: how well a kinematic model brings captures of one crossing together.

Each "pose" capture gives the crossing's position in the base frame: the model's camera pose at the
encoder readings combined with the measured position in the camera frame,

* ``z`` (the crossing's depth along the optical axis) = the sensor's reading + the mount's offset
  along the optical axis (``sensor_mount[2, 3]``),
* ``x = (u - cx) z / f``, ``y = (v - cy) z / f``.

For two captures of the same placement from different configurations, the truth is the same point: the
pair's error is the distance between the two positions projected on the artifact's plane. The metric is
the mean over all such pairs (in-view motions are not paired: their errors are below the repeatability
floor).

Approximation: the depth assumes the sensor's beam parallel to the optical axis and the plane square to
it. A plane tilted by phi from square puts the crossing's true depth ``r tan(phi)`` away from the
reading's, r the beam's distance from the optical axis (30 mm beside the camera: 0.5 um per mrad). That
error lies along the optical axis, nearly the plane's normal, which the projection removes; what is
left in the plane is ``r tan(phi) sin(phi)`` plus the scale error ``r tan(phi) / z`` on the in-image
offset (x, y): below 0.1 um for phi = 1 mrad and a crossing within 1 mm of the image centre.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from station.calibration._observations import CalibrationError, CameraModel, FloatArray, Observation
from station.kinematics import Kinematics

if TYPE_CHECKING:
    from station.calibration._result import CalibrationResult


def _kinematics(model: Kinematics | CalibrationResult) -> Kinematics:
    return model if isinstance(model, Kinematics) else model.kinematics()


def crossing_positions(
    observations: Sequence[Observation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
) -> FloatArray:
    """The crossing's position in the base frame (N, 3, mm) from each capture, as the module notes say.

    ``kinematics`` must have the camera as its tool. Captures without a sensor reading give NaN rows.
    """
    if not observations:
        return np.zeros((0, 3))
    mount = np.asarray(sensor_mount, dtype=float)
    q = np.array([o.joints_deg for o in observations], dtype=float)
    uv = np.array([o.center_px for o in observations], dtype=float)
    z = np.array([np.nan if o.z_mm is None else o.z_mm for o in observations]) + mount[2, 3]
    local = np.column_stack(
        [
            (uv[:, 0] - camera.principal_px[0]) * z / camera.focal_px,
            (uv[:, 1] - camera.principal_px[1]) * z / camera.focal_px,
            z,
        ]
    )
    C = _kinematics(kinematics).tool_pose(q)
    return np.asarray(np.einsum("nij,nj->ni", C[:, :3, :3], local) + C[:, :3, 3], dtype=float)


def pair_errors_um(
    observations: Sequence[Observation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
    *,
    plane_normals: Mapping[int, npt.ArrayLike] | None = None,
) -> FloatArray:
    """The error (um) of every pair of "pose" captures of one placement from different configurations.

    Parameters
    ----------
    observations
        Captures; only ``kind == "pose"`` ones with a sensor reading are used.
    kinematics
        The model judged (nominal, calibrated or true), with the camera as its tool; or a
        ``CalibrationResult`` (its calibrated kinematics).
    camera, sensor_mount
        The camera's intrinsics and the sensor's pose in the camera frame (4x4).
    plane_normals
        Each placement's plane normal (base frame); by default the mean optical axis of the model over
        the placement's captures (the captures look square at the plane).
    """
    used = [o for o in observations if o.kind == "pose" and o.z_mm is not None]
    if not used:
        return np.zeros(0)
    positions = crossing_positions(used, kinematics, camera, sensor_mount)
    placement = np.array([o.placement for o in used])
    config = np.array([o.configuration for o in used])
    axes = _kinematics(kinematics).tool_pose(np.array([o.joints_deg for o in used], dtype=float))[:, :3, 2]
    errors: list[FloatArray] = []
    for k in np.unique(placement):
        idx = np.flatnonzero(placement == k)
        if plane_normals is not None and int(k) in plane_normals:
            n = np.asarray(plane_normals[int(k)], dtype=float)
        else:
            n = axes[idx].mean(axis=0)
        n = n / np.linalg.norm(n)
        i, j = np.triu_indices(len(idx), k=1)
        keep = config[idx][i] != config[idx][j]
        diff = positions[idx][i[keep]] - positions[idx][j[keep]]
        in_plane = diff - np.outer(diff @ n, n)
        errors.append(np.linalg.norm(in_plane, axis=1) * 1000.0)
    return np.concatenate(errors) if errors else np.zeros(0)


def relative_error_um(
    observations: Sequence[Observation],
    kinematics: Kinematics | CalibrationResult,
    camera: CameraModel,
    sensor_mount: npt.ArrayLike,
    *,
    plane_normals: Mapping[int, npt.ArrayLike] | None = None,
) -> float:
    """The mean pair error (um) over the captures (see :func:`pair_errors_um` and the module notes).

    Raises
    ------
    CalibrationError
        No pair: the captures need two configurations of one placement, each with a sensor reading.
    """
    errors = pair_errors_um(observations, kinematics, camera, sensor_mount, plane_normals=plane_normals)
    if errors.size == 0:
        raise CalibrationError(
            "no pair of 'pose' captures of one placement from different configurations with sensor readings:"
            " the relative error needs at least two configurations per placement"
        )
    return float(errors.mean())


__all__ = ["crossing_positions", "pair_errors_um", "relative_error_um"]
