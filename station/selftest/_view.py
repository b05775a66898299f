"""The pure part of the joint-direction check: what the nominal model says a small joint move does to the
camera's view of the crossing, and how a measured change compares with it.

The view's change is a *signal* ``(du, dv, L * dtheta, S * ds)``: the crossing's shift in the image (px),
the turn of its groove nearest the image's x (rad) times a lever ``LEVER_PX``, and the relative change of
its scale (the grooves' width in px) times ``SCALE_LEVER_PX``, so that a turn about the optical axis
(joint 6 over a camera on the flange's axis) and a move along it (joint 2 or 3 where they move the
camera toward the artifact) weigh like a shift. The scene is taken as a
plane square to the optical axis at the working distance: over a move of a degree or two the nominal
model with that plane predicts the signal to a few per cent, far better than a direction check needs.
Frames: the base frame, the camera frame OpenCV's (x right, y down, z the optical axis); the groove's
direction in the image is ``(cos r, sin r)`` as :func:`station.vision.measure` reports it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from station.camera_model import CameraIntrinsics
from station.teach import Plane, crossing_on_plane

__all__ = ["LEVER_PX", "SCALE_LEVER_PX", "agreement", "predicted_signal", "signal", "wrap_cross_deg"]

FloatArray = npt.NDArray[np.float64]

LEVER_PX = 1000.0
"""The lever (px) that turns the groove's rotation (rad) into a shift-like figure (1 mrad: 1 px)."""
_FAR_PX = 100.0  # the second point along the groove the prediction follows
SCALE_LEVER_PX = 1000.0
"""The lever (px) that turns the relative change of the view's scale into a shift-like figure (0.1 %:
1 px)."""


def wrap_cross_deg(angle_deg: float) -> float:
    """An angle of the cross, which looks the same every 90 deg, into (-45, 45]."""
    a = (angle_deg + 45.0) % 90.0 - 45.0
    return 45.0 if a == -45.0 else a


def signal(du_px: float, dv_px: float, dturn_deg: float, dscale: float) -> FloatArray:
    """The view's change as ``(du, dv, LEVER_PX * dturn, SCALE_LEVER_PX * dscale)`` (px); ``dscale`` is
    the relative change of the view's scale (after / before - 1)."""
    return np.array(
        [du_px, dv_px, LEVER_PX * math.radians(dturn_deg), SCALE_LEVER_PX * dscale], dtype=np.float64
    )


def _project(camera_pose: FloatArray, point_mm: FloatArray, intrinsics: CameraIntrinsics) -> FloatArray:
    p = np.linalg.inv(camera_pose) @ np.append(point_mm, 1.0)
    if p[2] <= 0:
        raise ValueError("the point is behind the camera after the move")
    uv, _ = cv2.projectPoints(
        p[:3].reshape(1, 1, 3), np.zeros(3), np.zeros(3), intrinsics.camera_matrix, intrinsics.dist_coeffs
    )
    return np.asarray(uv.reshape(2), dtype=np.float64)


def predicted_signal(
    before: FloatArray,
    after: FloatArray,
    center_px: Sequence[float],
    rotation_deg: float,
    intrinsics: CameraIntrinsics,
    distance_mm: float,
) -> FloatArray:
    """The signal a move of the camera from pose ``before`` to ``after`` (4x4, base frame) should give,
    for a crossing seen at ``center_px`` with its groove at ``rotation_deg``, on a plane square to the
    optical axis ``distance_mm`` away."""
    axis = before[:3, 2]
    plane = Plane(before[:3, 3] + distance_mm * axis, -axis, 0.0)
    r = math.radians(rotation_deg)
    far_px = (float(center_px[0]) + _FAR_PX * math.cos(r), float(center_px[1]) + _FAR_PX * math.sin(r))
    a = crossing_on_plane(before, center_px, intrinsics, plane)
    b = crossing_on_plane(before, far_px, intrinsics, plane)
    pa, pb = _project(after, a, intrinsics), _project(after, b, intrinsics)
    qa, qb = _project(before, a, intrinsics), _project(before, b, intrinsics)
    turn = math.degrees(math.atan2(pb[1] - pa[1], pb[0] - pa[0])) - rotation_deg
    scale = float(np.linalg.norm(pb - pa)) / float(np.linalg.norm(qb - qa)) - 1.0
    return signal(pa[0] - float(center_px[0]), pa[1] - float(center_px[1]), wrap_cross_deg(turn), scale)


def agreement(predicted: FloatArray, measured: FloatArray) -> tuple[float, float]:
    """``(cosine, ratio)``: the cosine of the angle between the two signals (1: same direction, -1: the
    joint turns the other way) and ``|measured| / |predicted|``."""
    p, m = float(np.linalg.norm(predicted)), float(np.linalg.norm(measured))
    if p == 0.0:
        raise ValueError("the predicted signal is zero: the move changes nothing the camera can see")
    cosine = float(predicted @ measured) / (p * m) if m > 0.0 else 0.0
    return cosine, m / p
