"""Finding the target in one view: each visible chessboard corner, named and to a fraction of a pixel.

OpenCV's ChArUco detector finds the markers, names them and predicts each chessboard corner next to a
decoded marker from their local homography. Each corner is then refined by :func:`refine_corners`, the
Förstner operator [1]_ solved at the pixels themselves: OpenCV's own ``cornerSubPix`` resamples its window
bilinearly and pulls corners by up to a few hundredths of a pixel depending on where they fall within a
pixel (measured on the twin, noise-free: 0.012 px rms, correlated 0.74 with the sub-pixel phase; this
operator: 0.0001 px). With the nominal preset's noise, in focus: 0.009 px rms (``TARGET.md``).

References
----------
.. [1] W. Förstner and E. Gülch, "A fast operator for detection and precise location of distinct points,
   corners and centres of circular features", ISPRS Intercommission Conference on Fast Processing of
   Photogrammetric Data, Interlaken, 1987, pp. 281-305.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from station.camcal._errors import TargetNotFoundError
from station.camcal._target import STANDARD_TARGET, CharucoTarget
from station.vision import check_quality, to_gray8

__all__ = [
    "EDGE_MARGIN_PX",
    "MIN_CORNERS",
    "REFINE_SIGMA_PX",
    "TargetDetection",
    "detect_target",
    "refine_corners",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

EDGE_MARGIN_PX = 12.0
"""Corners nearer the frame's edge than this are dropped: the sub-pixel refinement's window would be cut
off there (measured on the twin: errors of 0.2-0.3 px within 8 px of the edge, under 0.05 px beyond 10)."""

REFINE_SIGMA_PX = 3.0
"""Gaussian weight of the corner refinement's window, px: wide enough to average the noise (0.009 px rms
in focus), narrow enough that the markers 1/5 of a square from each corner weigh nothing (the standard
target's nearest marker corner is 14 px away at 10 um/px, where the weight is 2e-5)."""

MIN_CORNERS = 12
"""Fewest corners a view must show to count (a homography needs 4; a view's pose and its share of the
distortion want many more)."""


@dataclass(frozen=True, eq=False)
class TargetDetection:
    """The target's corners found in one view.

    Attributes
    ----------
    ids : numpy.ndarray, (n,) int
        Corner ids (``CharucoTarget.corners_mm`` rows), ascending.
    corners_px : numpy.ndarray, (n, 2)
        Their image positions, px (0-based, pixel centres at integers, x right, y down).
    object_mm : numpy.ndarray, (n, 3)
        Their positions on the target, mm (z = 0).
    markers : int
        Markers decoded.
    image_size : (int, int)
        ``(width, height)`` of the view, px.
    """

    ids: IntArray
    corners_px: FloatArray
    object_mm: FloatArray
    markers: int
    image_size: tuple[int, int]

    @property
    def count(self) -> int:
        """Corners found."""
        return int(self.ids.size)

    def coverage(self) -> float:
        """Share of the image inside the convex hull of the corners found (0-1)."""
        hull = cv2.convexHull(self.corners_px.astype(np.float32))
        return float(cv2.contourArea(hull)) / float(self.image_size[0] * self.image_size[1])


def refine_corners(
    gray: npt.NDArray[np.uint8],
    corners_px: FloatArray,
    *,
    sigma_px: float = REFINE_SIGMA_PX,
    iterations: int = 10,
    max_shift_px: float = 1.5,
) -> tuple[FloatArray, npt.NDArray[np.bool_]]:
    """Refine chessboard corners to the point the grey-level gradients around them point away from.

    The Förstner operator: the point ``q`` minimising ``sum w(p) (g(p) . (p - q))^2`` over the pixels ``p``
    of a window, ``g`` the gradient (central differences) and ``w`` a Gaussian of sigma ``sigma_px``
    centred on ``q``; solved in closed form and iterated as the window follows ``q``. Nothing is resampled.

    Parameters
    ----------
    gray : numpy.ndarray
        The frame, 2-D.
    corners_px : numpy.ndarray, (n, 2)
        Starting points (x, y), px, within about a pixel of the corners.
    sigma_px : float
        The window's Gaussian weight; the window reaches ``3 sigma_px``.
    iterations : int
        Most iterations (it stops earlier once every point moves by less than 1e-5 px).
    max_shift_px : float
        A point that moves farther from its start is not a corner.

    Returns
    -------
    corners : numpy.ndarray, (n, 2)
        The refined points (the start where refinement failed).
    ok : numpy.ndarray, (n,) bool
        Refined: a window inside the frame, a well-conditioned solution, within ``max_shift_px``.
    """
    start = np.asarray(corners_px, dtype=np.float64).reshape(-1, 2)
    h, w = gray.shape
    reach = math.ceil(3.0 * sigma_px)
    ok = (
        (start[:, 0] >= reach + 1)
        & (start[:, 1] >= reach + 1)
        & (start[:, 0] <= w - reach - 2)
        & (start[:, 1] <= h - reach - 2)
    )
    q = start[ok].copy()
    if q.size == 0:
        return start.copy(), ok
    f = gray.astype(np.float64)
    gx, gy = np.zeros_like(f), np.zeros_like(f)
    gx[:, 1:-1] = (f[:, 2:] - f[:, :-2]) / 2.0
    gy[1:-1, :] = (f[2:, :] - f[:-2, :]) / 2.0
    offsets = np.arange(-reach, reach + 1)
    good = np.ones(len(q), dtype=bool)
    for _ in range(iterations):
        centre = np.clip(np.rint(q).astype(np.intp), [reach, reach], [w - reach - 1, h - reach - 1])
        ys = centre[:, 1, None, None] + offsets[None, :, None]
        xs = centre[:, 0, None, None] + offsets[None, None, :]
        gxx, gyy = gx[ys, xs], gy[ys, xs]
        wt = np.exp(
            -((xs - q[:, 0, None, None]) ** 2 + (ys - q[:, 1, None, None]) ** 2) / (2.0 * sigma_px**2)
        )
        a, b, d = (wt * gxx * gxx).sum((1, 2)), (wt * gxx * gyy).sum((1, 2)), (wt * gyy * gyy).sum((1, 2))
        rx = (wt * (gxx * gxx * xs + gxx * gyy * ys)).sum((1, 2))
        ry = (wt * (gxx * gyy * xs + gyy * gyy * ys)).sum((1, 2))
        det = a * d - b * b
        good &= det > 1e-6 * (a + d) ** 2
        safe = np.where(good, det, 1.0)
        new = np.column_stack([(d * rx - b * ry) / safe, (a * ry - b * rx) / safe])
        new[~good] = q[~good]
        moved = float(np.max(np.abs(new - q))) if len(q) else 0.0
        q = new
        if moved < 1e-5:
            break
    good &= np.hypot(*(q - start[ok]).T) <= max_shift_px
    out = start.copy()
    out[ok] = np.where(good[:, None], q, start[ok])
    ok[ok] = good
    return out, ok


def _detector(target: CharucoTarget) -> cv2.aruco.CharucoDetector:
    charuco = cv2.aruco.CharucoParameters()
    charuco.minMarkers = 1
    detector = cv2.aruco.DetectorParameters()
    detector.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE  # the chessboard corners are refined
    return cv2.aruco.CharucoDetector(target.board(), charuco, detector)


def detect_target(
    image: npt.ArrayLike,
    target: CharucoTarget = STANDARD_TARGET,
    *,
    min_corners: int = MIN_CORNERS,
    edge_margin_px: float = EDGE_MARGIN_PX,
) -> TargetDetection:
    """Find the target's chessboard corners in ``image``.

    Parameters
    ----------
    image : numpy.ndarray
        One frame: 8- or 16-bit grey, or BGR colour (converted as ``station.vision.to_gray8`` does).
    target : CharucoTarget
        The target in view.
    min_corners : int
        Fewest corners for a usable view (at least 4).
    edge_margin_px : float
        Corners nearer the frame's edge than this (px) are left out.

    Returns
    -------
    TargetDetection
        The corners found, with their ids and target positions.

    Raises
    ------
    station.vision.InvalidImageError, station.vision.ImageQualityError
        The frame is not an image, or blank or saturated.
    TargetNotFoundError
        Fewer than ``min_corners`` corners, with what was seen and what to do.
    """
    if min_corners < 4:
        raise ValueError(f"min_corners must be >= 4, got {min_corners}")
    if not (np.isfinite(edge_margin_px) and edge_margin_px >= 0):
        raise ValueError(f"edge_margin_px must be a finite value >= 0, got {edge_margin_px}")
    gray = to_gray8(np.asarray(image))
    check_quality(gray)
    corners, ids, _marker_corners, marker_ids = _detector(target).detectBoard(gray)
    markers = 0 if marker_ids is None else len(marker_ids)
    h, w = gray.shape
    pts = np.zeros((0, 2)) if ids is None else np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    ids_arr = np.zeros(0, np.int64) if ids is None else np.asarray(ids, dtype=np.int64).ravel()
    edge_margin_px = max(edge_margin_px, math.ceil(3.0 * REFINE_SIGMA_PX) + 2.0)
    pts, ok = refine_corners(gray, pts)
    keep = ok & (
        (pts[:, 0] >= edge_margin_px)
        & (pts[:, 1] >= edge_margin_px)
        & (pts[:, 0] <= w - 1 - edge_margin_px)
        & (pts[:, 1] <= h - 1 - edge_margin_px)
    )
    pts, ids_arr = pts[keep], ids_arr[keep]
    found = int(ids_arr.size)
    if found < min_corners:
        raise TargetNotFoundError(
            f"found {found} of the target's corners ({markers} markers decoded), need {min_corners}: "
            + _advice(markers, target)
        )
    order = np.argsort(ids_arr)
    pts, ids_arr = pts[order], ids_arr[order]
    return TargetDetection(ids_arr, pts, target.corners_mm()[ids_arr], markers, (w, h))


def _advice(markers: int, target: CharucoTarget) -> str:
    size = f"{target.squares_x} x {target.squares_y} squares of {target.square_mm} mm, {target.dictionary}"
    if markers == 0:
        return (
            f"no marker was decoded; is the calibration target ({size}) in view, lit and in focus (the "
            "distance sensor at the working distance)?"
        )
    return (
        f"too few markers were decoded to name the corners between them: bring the target into focus "
        f"and the camera square to it, and check that its description matches the board ({size})"
    )
