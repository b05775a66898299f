"""Compensated moves: the joints to send to the real arm so that the calibrated model reaches a pose.

The controller plans with its nominal table; the station does not ask it for a Cartesian pose. It
solves the inverse kinematics with the calibrated model itself (:func:`compensated_joints`) and sends a
joint move, split into steps within the driver's largest joint step (:func:`joint_steps`).

Poses are in the calibrated model's base frame. The structural parameters (the base row, ``d6``,
``theta6_offset``) stay at nominal, so that frame is the nominal one as far as the artifacts define
it: a pose relative to an artifact measured in that frame is reached with the calibrated accuracy.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from station.calibration._observations import CalibrationError, FloatArray
from station.kinematics import JOINTS, Kinematics


def compensated_joints(
    calibrated: Kinematics, camera_pose: npt.ArrayLike, *, current_deg: npt.ArrayLike
) -> FloatArray:
    """Joints (deg) that put the camera at ``camera_pose`` under the calibrated model.

    Parameters
    ----------
    calibrated
        The calibrated arm with the camera as its tool (``load_kinematics``).
    camera_pose
        4x4 requested camera pose, the calibrated model's base frame (mm).
    current_deg
        The arm's joints now: the solution nearest to them is chosen (same shoulder, elbow, wrist).

    Raises
    ------
    station.kinematics.UnreachableError
        No solution within the joint limits.
    """
    return calibrated.inverse(camera_pose, seed_deg=current_deg, tool=True)


def joint_steps(start_deg: npt.ArrayLike, end_deg: npt.ArrayLike, *, max_step_deg: float) -> list[FloatArray]:
    """Waypoints from ``start_deg`` to ``end_deg`` (excluded, included) along a straight line in joint
    space, each within ``max_step_deg`` of the previous on every joint; the last is ``end_deg`` exactly."""
    a = np.asarray(start_deg, dtype=float)
    b = np.asarray(end_deg, dtype=float)
    if (
        a.shape != (JOINTS,)
        or b.shape != (JOINTS,)
        or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b)))
    ):
        raise CalibrationError(
            f"start_deg and end_deg must be {JOINTS} finite angles, got {a.shape} and {b.shape}"
        )
    if not (math.isfinite(max_step_deg) and max_step_deg > 0):
        raise CalibrationError(f"max_step_deg must be > 0, got {max_step_deg!r}")
    span = float(np.max(np.abs(b - a)))
    n = max(1, math.ceil(span / max_step_deg - 1e-12))
    return [a + (b - a) * (i / n) for i in range(1, n)] + [b.copy()]


def compensated_steps(
    calibrated: Kinematics,
    camera_pose: npt.ArrayLike,
    *,
    current_deg: npt.ArrayLike,
    max_step_deg: float,
) -> list[FloatArray]:
    """The joint waypoints of a compensated move: :func:`compensated_joints`, split by :func:`joint_steps`."""
    target = compensated_joints(calibrated, camera_pose, current_deg=current_deg)
    return joint_steps(current_deg, target, max_step_deg=max_step_deg)


__all__ = ["compensated_joints", "compensated_steps", "joint_steps"]
