"""Where the fit starts: the artifacts' and the rulers' placements from the captures under the nominal model.

A crossing's captures each give its position in the base frame (``crossing_positions``): their mean
places the artifact. A ruler's frames each give the point under the reference pixel (``ruler_points``)
and where it lies on the ruler (``s``, ``t``): a line fitted to the points against ``s`` gives the
ruler's direction and graduation 0; the taught normal, made square to it, the rest. With fewer than
two frames far enough apart the taught direction is kept and only the origin moves.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from station.calibration._absolute import ruler_points
from station.calibration._metric import crossing_positions
from station.calibration._model import CalibrationModel
from station.calibration._observations import FloatArray, Observation
from station.calibration._ruler_observations import RulerObservation

MIN_SPAN_MM = 5.0
"""A ruler's frames spanning less than this along it keep the taught direction."""


def initial_artifacts(model: CalibrationModel, observations: Sequence[Observation]) -> FloatArray:
    """Errors with the artifacts' positions from the captures under the nominal model (the mean crossing
    position per placement); the nominal position where a placement has no capture with a reading."""
    delta = model.zeros()
    kin = model.kinematics(delta)
    setup = model.setup
    for i, k in enumerate(model.placements):
        seen = [o for o in observations if o.placement == k and o.z_mm is not None]
        if not seen:
            continue
        p = np.nanmean(crossing_positions(seen, kin, setup.camera, setup.sensor_mount), axis=0)
        delta[model.artifact_delta_indices(i)[:3]] = p - np.asarray(setup.artifacts[k], dtype=float)
    return delta


def rotation_angles(R: FloatArray) -> tuple[float, float, float]:
    """``(a, b, c)`` (rad) with ``R = Rx(a) Ry(b) Rz(c)``."""
    b = math.asin(max(-1.0, min(1.0, float(R[0, 2]))))
    return math.atan2(-float(R[1, 2]), float(R[2, 2])), b, math.atan2(-float(R[0, 1]), float(R[0, 0]))


def initial_rulers(
    model: CalibrationModel, rulers: Sequence[RulerObservation], delta: FloatArray
) -> FloatArray:
    """``delta`` with each ruler's origin and direction from its frames under the nominal model."""
    out = delta.copy()
    setup = model.setup
    kin = model.kinematics(model.zeros())
    for i, r in enumerate(model.rulers):
        frames = [o for o in rulers if o.ruler == r]
        if not frames:
            continue
        points = ruler_points(frames, kin, setup.camera, setup.sensor_mount)
        st = np.array([(o.position_mm, o.offset_mm) for o in frames])
        R0 = setup.rulers[r].frame()
        s_axis, t_axis, down = R0[:, 0], R0[:, 1], R0[:, 2]
        on_axis = points - st[:, 1:2] * t_axis
        if np.ptp(st[:, 0]) >= MIN_SPAN_MM:
            A = np.column_stack([np.ones(len(st)), st[:, 0]])
            coef, *_ = np.linalg.lstsq(A, on_axis, rcond=None)
            s_axis = coef[1] - (coef[1] @ down) * down
            s_axis = s_axis / np.linalg.norm(s_axis)
        origin = np.mean(on_axis - st[:, :1] * s_axis, axis=0)
        R = np.column_stack([s_axis, np.cross(down, s_axis), down])
        idx = model.ruler_delta_indices(i)
        out[idx[:3]] = origin - np.asarray(setup.rulers[r].origin_mm, dtype=float)
        out[idx[3:]] = np.degrees(rotation_angles(R0.T @ R))
    return out


__all__ = ["initial_artifacts", "initial_rulers", "rotation_angles"]
