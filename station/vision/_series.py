"""Series-level calibration: one image-to-artifact homography for a whole series of images.

Per image, the seed scales by the image's own four vertices (~80 px apart); noise in them becomes a
scale error that moves points far from the square, the image origin ~300-400 px away, by a few
hundredths of a pixel (accuracy.md, "per-image scale"). When the camera and the artifact plane stay
the same across a series (a validation on the X-Y table, a repeatability session), one homography fits
all images: the vertices of image k map to the groove-width square shifted by a per-image translation
t_k (the artifact moved in its plane). Solved by alternating least squares: given the t_k, a DLT over
all 4N vertices; given H, each t_k as the mean offset of its mapped vertices.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._errors import GeometryError
from station.vision._geometry import apply_homography, square_homography

FloatArray = npt.NDArray[np.float64]


def series_homography(
    corners_px: Sequence[FloatArray], width_mm: float, *, iterations: int = 4
) -> FloatArray:
    """One homography image px -> artifact mm for a series, from each image's four vertices.

    Parameters
    ----------
    corners_px : sequence of (4, 2) arrays
        Each image's vertices in the order top-left, top-right, bottom-right, bottom-left.
    width_mm : float
        The groove width (the square's side).

    Returns
    -------
    (3, 3) array, defined up to a translation of the artifact frame (which cancels in positions
    relative to the image origin and in displacements).
    """
    if len(corners_px) < 1:
        raise ValueError("a series needs at least one image")
    w = width_mm
    square = np.array([[0.0, 0.0], [w, 0.0], [w, w], [0.0, w]])
    src = np.concatenate([np.asarray(c, np.float64).reshape(4, 2) for c in corners_px])
    H = square_homography(np.asarray(corners_px[0], np.float64), w)
    for _ in range(iterations):
        mapped = apply_homography(H, src).reshape(-1, 4, 2)
        shifts = (mapped - square[None, :, :]).mean(axis=1)
        dst = (square[None, :, :] + shifts[:, None, :]).reshape(-1, 2)
        H_new, _ = cv2.findHomography(src, dst, 0)
        if H_new is None or not np.all(np.isfinite(H_new)):
            raise GeometryError("the series' vertices are degenerate: no common projective transform")
        H = np.asarray(H_new, np.float64)
    return H


def series_centers_mm(
    centers_px: Sequence[tuple[float, float]], corners_px: Sequence[FloatArray], width_mm: float
) -> FloatArray:
    """Each image's ``center_mm`` (the crossing relative to the image origin, mm, artifact axes) with
    the series' common homography instead of the image's own. Returns (N, 2)."""
    H = series_homography(corners_px, width_mm)
    pts = np.asarray(centers_px, np.float64).reshape(-1, 2)
    origin = apply_homography(H, np.zeros((1, 2)))[0]
    return apply_homography(H, pts) - origin
