"""The camera model's part in a ruler measurement: undistorted pixel coordinates and the reference.

Without a camera model the ruler is measured in pixel coordinates, under the image's origin pixel
(0, 0). With one, every pixel's coordinates are undistorted (OpenCV's model) into an ideal camera
with square pixels (focal length ``sqrt(fx fy)``, the same principal point), and the ruler is
measured under the principal point, where the optical axis meets it.
"""

from __future__ import annotations

import math
from functools import lru_cache

import cv2
import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

Coords = tuple[FloatArray, FloatArray]


@lru_cache(maxsize=4)
def _grid(matrix: tuple[float, ...], dist: tuple[float, ...], height: int, width: int) -> Coords | None:
    k = np.array(matrix, dtype=np.float64).reshape(3, 3)
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    f = math.sqrt(fx * fy)
    if not any(dist) and fx == fy and k[0, 1] == 0:
        return None
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float64)
    if any(dist):
        points = np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2)
        ideal = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
        out = cv2.undistortPointsIter(points, k, np.array(dist, dtype=np.float64), np.eye(3), ideal, criteria)
        grid = np.asarray(out, dtype=np.float64).reshape(height, width, 2)
        ux, uy = np.ascontiguousarray(grid[..., 0]), np.ascontiguousarray(grid[..., 1])
    else:
        yn = (ys - cy) / fy
        xn = (xs - cx - k[0, 1] * yn) / fx
        ux, uy = np.asarray(cx + f * xn, dtype=np.float64), np.asarray(cy + f * yn, dtype=np.float64)
    ux.setflags(write=False)
    uy.setflags(write=False)
    return ux, uy


def lens_coordinates(
    camera_matrix: list[list[float]] | None, dist_coeffs: list[float] | None, shape: tuple[int, int]
) -> tuple[Coords | None, tuple[float, float]]:
    """``(coordinates, reference point)``: undistorted pixel coordinates (None: the pixel centres)
    and the point measured under (the principal point with a camera model, else (0, 0))."""
    if camera_matrix is None:
        return None, (0.0, 0.0)
    k = tuple(float(v) for row in camera_matrix for v in row)
    dist = tuple(float(v) for v in (dist_coeffs or ()))
    return _grid(k, dist, shape[0], shape[1]), (k[2], k[5])
