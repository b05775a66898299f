"""The calibration target's render kernels (``sim.target``): rays, cell coverage and reflectance.

What does not change from frame to frame is kept: each true camera's pixel rays (the lens inverted over
the image, the costliest step that depends on the camera alone) and the target's face, in small bounded
caches keyed on everything they are computed from.

The reflectance is ``sum over cells of (column coverage) x (row coverage) x (cell's reflectance)``, with
each coverage the difference of two ``box_step`` values ("beyond" a cell line), as ``sim.target`` states
it. Most cell lines separate two cells of the same colour (a chessboard square is ten cells of one
colour; a marker's bits come in runs): summed by parts, a column line's beyond-value is multiplied by the
difference of the cells on its two sides, over the rows the pixel sees, so where that difference is zero
the value drops out of the sum exactly and any value does. Those lines get the cheap 0 / 1 value of a
far pixel instead of ``box_step``: the same image up to floating-point rounding (about 1e-13 DN), for
a third or less of the work (the four normal CDFs of each ``box_step`` value are most of a frame's cost).
"""

from __future__ import annotations

from collections import OrderedDict
from functools import lru_cache
from threading import Lock

import cv2
import numpy as np
import numpy.typing as npt

from sim._render_features import vignetting_map
from sim._render_geometry import Float32Array, FloatArray, box_step_sorted, cutoff_px
from station.camcal import CharucoTarget
from station.camera_model import CameraIntrinsics

__all__ = ["cached_vignetting", "pixel_rays", "reflectance", "target_face"]

_UNDISTORT_TOL_PX = 1e-6
_RAY_CACHE_SIZE = 4
"""True cameras whose rays are kept: 7.4 MB each at 640 x 480 (a session renders through one)."""
_rays: OrderedDict[tuple[bytes, bytes, tuple[int, int]], FloatArray] = OrderedDict()
_rays_lock = Lock()

IntArray = npt.NDArray[np.intp]


def pixel_rays(intrinsics: CameraIntrinsics, shape: tuple[int, int]) -> FloatArray:
    """Homogeneous undistorted rays ``(x, y, 1)`` of every pixel centre, ``(h, w, 3)``, read-only.

    Checked by re-projection to 1e-6 px (ValueError where the distortion cannot be inverted); computed
    once per camera matrix, distortion and image shape (the last few kept).
    """
    K = np.ascontiguousarray(intrinsics.camera_matrix, dtype=np.float64)
    dist = np.ascontiguousarray(intrinsics.dist_coeffs, dtype=np.float64)
    key = (K.tobytes(), dist.tobytes(), (int(shape[0]), int(shape[1])))
    with _rays_lock:
        hit = _rays.get(key)
        if hit is not None:
            _rays.move_to_end(key)
            return hit
    rays = _undistorted_rays(K, dist, key[2])
    out = np.concatenate([rays, np.ones((*key[2], 1))], axis=2)
    out.setflags(write=False)
    with _rays_lock:
        _rays[key] = out
        while len(_rays) > _RAY_CACHE_SIZE:
            _rays.popitem(last=False)
    return out


def _undistorted_rays(K: FloatArray, dist: FloatArray, shape: tuple[int, int]) -> FloatArray:
    """Undistorted normalised coordinates of every pixel centre, (h, w, 2), checked by re-projection."""
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w].astype(np.float64)
    px = np.stack([xs.ravel(), ys.ravel()], axis=1).reshape(-1, 1, 2)
    rays = np.asarray(cv2.undistortPoints(px, K, dist), dtype=np.float64).reshape(-1, 2)
    # The inversion fails first where the distortion is strongest, at the frame's edge: check the edge
    # rows and columns and every 7th pixel, and the rest only if any of those fails.
    grid = np.zeros((h, w), dtype=bool)
    grid[::7, ::7] = grid[[0, -1], :] = grid[:, [0, -1]] = True
    sample = np.flatnonzero(grid.ravel())
    back = _project(np.column_stack([rays[sample], np.ones(sample.size)]), K, dist)
    if np.max(np.hypot(*(back - px[sample].reshape(-1, 2)).T)) > _UNDISTORT_TOL_PX:
        back = _project(np.column_stack([rays, np.ones(len(rays))]), K, dist)
        sample = np.arange(h * w)
    bad = sample[np.hypot(*(back - px[sample].reshape(-1, 2)).T) > _UNDISTORT_TOL_PX]
    if bad.size:
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-15)
        exact = cv2.undistortPointsIter(px[bad], K, dist, np.eye(3), np.eye(3), criteria)
        rays[bad] = np.asarray(exact, dtype=np.float64).reshape(-1, 2)
        back = _project(np.column_stack([rays[bad], np.ones(bad.size)]), K, dist)
        if np.max(np.hypot(*(back - px[bad].reshape(-1, 2)).T)) > _UNDISTORT_TOL_PX:
            raise ValueError("the lens's distortion cannot be inverted over the image: it is too strong")
    return rays.reshape(h, w, 2)


def _project(points: FloatArray, K: FloatArray, dist: FloatArray) -> FloatArray:
    out, _ = cv2.projectPoints(points.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return np.asarray(out.reshape(-1, 2), dtype=np.float64)


@lru_cache(maxsize=4)
def target_face(target: CharucoTarget, cells_per_square: int) -> FloatArray:
    """The target's face at ``cells_per_square``: reflectance 0 (black) or 1 (white) per cell, read-only."""
    face = target.pattern(cells_per_square).astype(np.float64) / 255.0
    face.setflags(write=False)
    return face


@lru_cache(maxsize=8)
def cached_vignetting(shape: tuple[int, int], strength: float) -> Float32Array:
    """``sim._render_features.vignetting_map`` (read-only), kept per image shape and strength."""
    return vignetting_map(shape, strength)


class _Axis:
    """One axis of the target (u: columns of cells, v: rows) as the pixels see it."""

    def __init__(self, coord: FloatArray, cell_mm: float, sigma_px: float) -> None:
        d_dy, d_dx = np.gradient(coord)
        norm = np.hypot(d_dx, d_dy)
        reach_mm = cutoff_px(sigma_px) * norm
        self.coord, self.norm = coord, norm
        self.first: IntArray = np.floor((coord - reach_mm) / cell_mm).astype(np.intp)
        # cells first .. last can cover the pixel; the others' coverage is exactly 0
        self.span: IntArray = np.floor((coord + reach_mm) / cell_mm).astype(np.intp) - self.first + 1
        self.count = int(np.max(self.span))
        cos_abs, sin_abs = np.abs(d_dx) / norm, np.abs(d_dy) / norm
        self.wide, self.narrow = np.maximum(cos_abs, sin_abs), np.minimum(cos_abs, sin_abs)

    def coverage(self, cell_mm: float, sigma_px: float, visible: list[npt.NDArray[np.bool_]]) -> FloatArray:
        """Coverage of cells ``first + k``, ``(count, h, w)``; line ``first + k``'s beyond-value is exact
        where ``visible[k]``, and the far pixel's 0 / 1 elsewhere (see the module's docstring)."""
        cut = cutoff_px(sigma_px)
        beyond = []
        for k in range(self.count + 1):
            d = (self.coord - (self.first + k) * cell_mm) / self.norm
            out = (d > 0.0).astype(np.float64)  # beyond the cut-off a pixel is on one side (box_step's 1e-13)
            near = np.flatnonzero((np.abs(d) < cut) & visible[k])
            if near.size:
                out.flat[near] = box_step_sorted(
                    d.flat[near], self.wide.flat[near], self.narrow.flat[near], sigma_px
                )
            beyond.append(out)
        return np.stack([beyond[k] - beyond[k + 1] for k in range(self.count)])


def _window_any(change: npt.NDArray[np.bool_], count: int) -> npt.NDArray[np.bool_]:
    """``out[n, r, c]``: any of ``change[r : r + n, c]`` (n = 0 .. count), for windows inside the array."""
    rows = change.shape[0]
    sums = np.zeros((rows + 1, change.shape[1]), dtype=np.int32)
    np.cumsum(change, axis=0, out=sums[1:])
    out = np.zeros((count + 1, *change.shape), dtype=bool)
    for n in range(1, min(count, rows) + 1):
        out[n, : rows - n + 1] = sums[n:] > sums[:-n]
    return out


def _visible_lines(
    change: npt.NDArray[np.bool_], along: _Axis, across: _Axis, across_lo: int, along_lo: int
) -> list[npt.NDArray[np.bool_]]:
    """For each line ``along.first + k``: does a colour change cross it within the pixel's cells across?

    ``change[r, c]`` (board rows along ``across``, columns along ``along``): the cells either side of line
    ``c`` differ in row ``r``. The two outermost lines are always exact (the sum holds no cell beyond).
    """
    windows = _window_any(change, across.count).ravel()
    rows, cols = change.shape
    base = (across.span * rows + (across.first - across_lo)) * cols + (along.first - along_lo)
    ones = np.ones(base.shape, dtype=bool)
    inner = [windows.take(base + k) for k in range(1, along.count)]
    return [ones, *inner, ones]


def reflectance(
    u: FloatArray, v: FloatArray, face: FloatArray, cell_mm: float, sigma_px: float
) -> FloatArray:
    """Each pixel's reflectance (0 black .. 1 white) for the target coordinates ``u``, ``v`` (mm) at its
    centre: the cells' coverage (``box_step`` of the cell lines, blur ``sigma_px``) times their face
    values, white beyond the face."""
    cu, cv = _Axis(u, cell_mm, sigma_px), _Axis(v, cell_mm, sigma_px)
    pad = max(cu.count, cv.count) + 1
    i_lo, j_lo = int(cu.first.min()) - pad, int(cv.first.min()) - pad
    i_hi, j_hi = int(cu.first.max()) + cu.count + pad, int(cv.first.max()) + cv.count + pad
    board = np.ones((j_hi - j_lo, i_hi - i_lo))  # white beyond the pattern
    js, is_ = max(0, -j_lo), max(0, -i_lo)
    je, ie = min(board.shape[0], face.shape[0] - j_lo), min(board.shape[1], face.shape[1] - i_lo)
    if je > js and ie > is_:
        board[js:je, is_:ie] = face[js + j_lo : je + j_lo, is_ + i_lo : ie + i_lo]
    col_change = np.ones(board.shape, dtype=bool)  # [j, i]: cells i - 1 and i differ in row j
    col_change[:, 1:] = board[:, 1:] != board[:, :-1]
    row_change = np.ones(board.shape, dtype=bool)  # [j, i]: cells j - 1 and j differ in column i
    row_change[1:, :] = board[1:, :] != board[:-1, :]
    cols = cu.coverage(cell_mm, sigma_px, _visible_lines(col_change, cu, cv, j_lo, i_lo))
    rows = cv.coverage(cell_mm, sigma_px, _visible_lines(row_change.T, cv, cu, i_lo, j_lo))
    width = board.shape[1]
    flat = board.ravel()
    base = (cv.first - j_lo) * width + (cu.first - i_lo)
    out = np.zeros(u.shape)
    for m in range(rows.shape[0]):
        at = base + m * width
        line = cols[0] * flat.take(at)
        for k in range(1, cols.shape[0]):
            line += cols[k] * flat.take(at + k)
        out += rows[m] * line
    return out
