"""Following the target's corners into the blur: a square view out of the markers' depth of field.

Behind the station's 1X macro lens the ArUco markers are read within about +/-0.6 mm of focus (a blur of
2.2 px sigma at f/4); the focal length's scale from heights (``station.camcal._heights``) wants a wider span.
A chessboard corner is the image of the corner under any blur symmetric about it, so the corners stay
usable long after the markers that name them are lost: a view square to the target, moved along the
optical axis by ``dz`` from a view in focus of the same turn, shows the in-focus view's corners scaled
about the principal point by ``Z0 / (Z0 + dz)``; each is predicted there (shifted by the phase
correlation of the two frames), refined (``refine_corners``), the affine map from the prediction to the
refined corners re-predicts them all, and they are refined once more from it. A corner that moves
farther than ``max_shift_px`` from that prediction is left out.

How far it holds is the blur's growth times the height against the markers' margin: beyond a blur of
about 4 px sigma the nearest marker's light reaches the refinement's window and pulls the corner
(``TARGET.md``: the bias against the height, measured on noise-free twin frames).
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from station.camcal._detect import (
    EDGE_MARGIN_PX,
    MIN_CORNERS,
    REFINE_SIGMA_PX,
    TargetDetection,
    refine_corners,
)
from station.camcal._errors import TargetNotFoundError
from station.vision import check_quality, to_gray8

__all__ = ["follow_target"]

FloatArray = npt.NDArray[np.float64]


def follow_target(
    image: npt.ArrayLike,
    reference: TargetDetection,
    reference_image: npt.ArrayLike,
    *,
    scale: float,
    centre_px: tuple[float, float],
    sigma_px: float = REFINE_SIGMA_PX,
    max_shift_px: float = 0.5,
    min_corners: int = MIN_CORNERS,
    edge_margin_px: float = EDGE_MARGIN_PX,
) -> TargetDetection:
    """The corners of ``reference`` found again in ``image``, a view of the same turn at another height.

    Parameters
    ----------
    image : numpy.ndarray
        The out-of-focus frame (8- or 16-bit grey, or BGR).
    reference : TargetDetection
        The in-focus view of the same turn (``detect_target``).
    reference_image : numpy.ndarray
        Its frame: scaled, it gives the shift between the views (phase correlation), which the arm's
        motion makes up to tens of pixels when its model is not yet calibrated.
    scale : float
        The image scale of ``image`` against ``reference``'s: ``Z0 / (Z0 + dz)``, ``dz`` the camera's move
        away from the target (the sensor's readings' difference) and ``Z0`` the working distance.
    centre_px : (float, float)
        The point the image scales about (the principal point; the image centre is near enough).
    sigma_px : float
        The refinement's window (``refine_corners``).
    max_shift_px : float
        A refined corner farther than this from that prediction (the affine map's) is left out.
    min_corners, edge_margin_px
        As ``detect_target``'s.

    Raises
    ------
    TargetNotFoundError
        Fewer than ``min_corners`` corners refined, with what to do.
    """
    if not (np.isfinite(scale) and 0.5 < scale < 2.0):
        raise ValueError(f"scale must be a finite image scale in (0.5, 2), got {scale!r}")
    gray = to_gray8(np.asarray(image))
    check_quality(gray)
    h, w = gray.shape
    if (w, h) != reference.image_size:
        raise TargetNotFoundError(
            f"the frame is {w} x {h} px but the in-focus view was {reference.image_size[0]} x "
            f"{reference.image_size[1]} px: take every view with one camera setting"
        )
    c = np.asarray(centre_px, dtype=np.float64)
    predicted = (
        c + (reference.corners_px - c) * scale + _shift(gray, to_gray8(np.asarray(reference_image)), scale, c)
    )
    pts, ok = refine_corners(gray, predicted, sigma_px=sigma_px)
    if int(ok.sum()) >= 3:
        # the arm's move is not exactly along the axis (and the centre not exactly the principal point):
        # the affine map from the prediction to the refined corners re-predicts them all, the lens's
        # distortion kept in the prediction (least squares, deterministic: the same frames give the
        # same corners)
        predicted = _affine(predicted, pts, ok, max_shift_px)
        pts, ok = refine_corners(gray, predicted, sigma_px=sigma_px)
        ok &= np.hypot(*(pts - predicted).T) <= max_shift_px
    margin = max(edge_margin_px, np.ceil(3.0 * sigma_px) + 2.0)
    keep = ok & (
        (pts[:, 0] >= margin)
        & (pts[:, 1] >= margin)
        & (pts[:, 0] <= w - 1 - margin)
        & (pts[:, 1] <= h - 1 - margin)
    )
    if int(keep.sum()) < min_corners:
        raise TargetNotFoundError(
            f"followed {int(keep.sum())} of the in-focus view's {reference.count} corners into this view, "
            f"need {min_corners}: take the square views nearer focus (smaller heights)"
        )
    return TargetDetection(
        reference.ids[keep], pts[keep], reference.object_mm[keep], reference.markers, reference.image_size
    )


def _shift(
    gray: npt.NDArray[np.uint8], reference: npt.NDArray[np.uint8], scale: float, c: FloatArray
) -> FloatArray:
    """The shift (px) of ``gray`` against ``reference`` scaled by ``scale`` about ``c``: phase correlation."""
    M = np.array([[scale, 0.0, (1.0 - scale) * c[0]], [0.0, scale, (1.0 - scale) * c[1]]])
    h, w = gray.shape
    warped = cv2.warpAffine(reference.astype(np.float32), M, (w, h), borderMode=cv2.BORDER_REFLECT)
    window = cv2.createHanningWindow((w, h), cv2.CV_32F)
    (dx, dy), _response = cv2.phaseCorrelate(warped, gray.astype(np.float32), window)
    return np.array([dx, dy], dtype=np.float64)


def _affine(
    predicted: FloatArray, refined: FloatArray, ok: npt.NDArray[np.bool_], limit_px: float
) -> FloatArray:
    """``predicted`` mapped by the affine map that best sends it onto ``refined`` (where ``ok``), fitted
    once more without the corners it leaves beyond ``limit_px``."""
    use = ok.copy()
    A = np.column_stack([predicted, np.ones(len(predicted))])
    for _ in range(2):
        M, *_ = np.linalg.lstsq(A[use], refined[use], rcond=None)
        near = ok & (np.hypot(*(A @ M - refined).T) <= limit_px)
        if int(near.sum()) < 3 or np.array_equal(near, use):
            break
        use = near
    return np.asarray(A @ M, dtype=np.float64)
