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

__all__ = ["cached_vignetting", "pixel_rays", "scene", "target_face"]

_UNDISTORT_TOL_PX = 1e-6
_RAY_CACHE_SIZE = 4
"""True cameras whose rays are kept: 7.4 MB each at 640 x 480 (a session renders through one)."""
_rays: OrderedDict[tuple[bytes, bytes, tuple[int, int]], FloatArray] = OrderedDict()
_rays_lock = Lock()

IntArray = npt.NDArray[np.intp]

_BAND_PIXELS = 16384
"""Pixels per band of rows the scene is computed in (25 rows of 640): each band's arrays (128 kB each)
stay in the processor's cache."""


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
    """One axis of the target (u: columns of cells, v: rows) as a band of pixels sees it."""

    def __init__(
        self, coord: FloatArray, d_dx: FloatArray, d_dy: FloatArray, cell_mm: float, cut: float
    ) -> None:
        norm = np.hypot(d_dx, d_dy)
        reach_mm = cut * norm
        self.coord, self.norm = coord, norm
        self.first: IntArray = np.floor((coord - reach_mm) / cell_mm).astype(np.intp)
        # cells first .. first + span - 1 can cover the pixel; the others' coverage is exactly 0
        self.span: IntArray = np.floor((coord + reach_mm) / cell_mm).astype(np.intp) - self.first + 1
        self.count = int(np.max(self.span))
        cos_abs, sin_abs = np.abs(d_dx) / norm, np.abs(d_dy) / norm
        self.wide, self.narrow = np.maximum(cos_abs, sin_abs), np.minimum(cos_abs, sin_abs)

    def coverage(self, cell_mm: float, sigma_px: float, visible: npt.NDArray[np.bool_]) -> FloatArray:
        """Coverage of cells ``first + k``, ``(count, n)``; inner line ``first + k``'s beyond-value
        (``k = 1 .. count - 1``, ``visible[k - 1]``) is exact where visible and the far pixel's 0 / 1
        elsewhere (see the module's docstring). The outer lines are beyond the cut-off by construction
        (``first``, ``span``): 1 and 0."""
        lines = np.arange(1, self.count)[:, None]
        d = (self.coord - (self.first + lines) * cell_mm) / self.norm  # (count - 1, n), px
        beyond = np.empty((self.count + 1, d.shape[1]))
        beyond[0], beyond[-1] = 1.0, 0.0
        inner = beyond[1:-1]
        np.greater(d, 0.0, out=inner)  # beyond the cut-off a pixel is on one side (box_step's 1e-13)
        at = np.flatnonzero((np.abs(d) < cutoff_px(sigma_px)) & visible)
        if at.size:
            pixel = at % d.shape[1]
            inner.flat[at] = box_step_sorted(d.flat[at], self.wide[pixel], self.narrow[pixel], sigma_px)
        return beyond[:-1] - beyond[1:]


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
) -> npt.NDArray[np.bool_]:
    """For each inner line ``along.first + k`` (``k = 1 .. count - 1``): does a colour change cross it
    within the pixel's cells across? ``(count - 1, n)``.

    ``change[r, c]`` (board rows along ``across``, columns along ``along``): the cells either side of line
    ``c`` differ in row ``r``.
    """
    windows = _window_any(change, across.count).ravel()
    rows, cols = change.shape
    base = (across.span * rows + (across.first - across_lo)) * cols + (along.first - along_lo)
    return windows.take(base + np.arange(1, along.count)[:, None])


def _board(face: FloatArray, cu: _Axis, cv: _Axis) -> tuple[FloatArray, int, int]:
    """The face's cells the band's pixels can see, white beyond the face, and its first column and row."""
    pad = max(cu.count, cv.count) + 1
    i_lo, j_lo = int(cu.first.min()) - pad, int(cv.first.min()) - pad
    i_hi, j_hi = int(cu.first.max()) + cu.count + pad, int(cv.first.max()) + cv.count + pad
    board = np.ones((j_hi - j_lo, i_hi - i_lo))  # white beyond the pattern
    js, is_ = max(0, -j_lo), max(0, -i_lo)
    je, ie = min(board.shape[0], face.shape[0] - j_lo), min(board.shape[1], face.shape[1] - i_lo)
    if je > js and ie > is_:
        board[js:je, is_:ie] = face[js + j_lo : je + j_lo, is_ + i_lo : ie + i_lo]
    return board, i_lo, j_lo


def _band_reflectance(
    u: FloatArray,
    v: FloatArray,
    du_dx: FloatArray,
    du_dy: FloatArray,
    dv_dx: FloatArray,
    dv_dy: FloatArray,
    face: FloatArray,
    cell_mm: float,
    sigma_px: float,
) -> FloatArray:
    """The reflectance of a band of pixels (see :func:`scene`), flat arrays of its pixels."""
    cut = cutoff_px(sigma_px)
    cu, cv = _Axis(u, du_dx, du_dy, cell_mm, cut), _Axis(v, dv_dx, dv_dy, cell_mm, cut)
    board, i_lo, j_lo = _board(face, cu, cv)
    col_change = np.ones(board.shape, dtype=bool)  # [j, i]: cells i - 1 and i differ in row j
    col_change[:, 1:] = board[:, 1:] != board[:, :-1]
    row_change = np.ones(board.shape, dtype=bool)  # [j, i]: cells j - 1 and j differ in column i
    row_change[1:, :] = board[1:, :] != board[:-1, :]
    cols = cu.coverage(cell_mm, sigma_px, _visible_lines(col_change, cu, cv, j_lo, i_lo))
    rows = cv.coverage(cell_mm, sigma_px, _visible_lines(row_change.T, cv, cu, i_lo, j_lo))
    width = board.shape[1]
    flat = board.ravel()
    base = (cv.first - j_lo) * width + (cu.first - i_lo) + np.arange(cols.shape[0])[:, None]
    out = np.zeros(u.shape)
    for m in range(rows.shape[0]):
        out += rows[m] * np.einsum("kn,kn->n", cols, flat.take(base + m * width))
    return out


def scene(
    rays: FloatArray,
    rotation: FloatArray,
    translation_mm: FloatArray,
    face: FloatArray,
    cell_mm: float,
    sigma_px: float,
) -> tuple[FloatArray, FloatArray]:
    """Each pixel's reflectance (0 black .. 1 white) and the depth (mm) of the target point it sees.

    ``rays``: :func:`pixel_rays`; the target's pose in the camera (``X = rotation X_target + translation``);
    ``face``: :func:`target_face`, cells ``cell_mm`` square; ``sigma_px``: the optics' blur in focus.
    The pixel's reflectance is the cells' coverage (``box_step`` of the cell lines) times their face
    values, white beyond the face. Computed in bands of rows (each band's arrays stay in the processor's
    cache), the gradients of the target coordinates from a row beyond the band each side, as over the
    whole image. ValueError when the target's plane does not fill the view (a horizon in it).
    """
    R, t = rotation, translation_mm
    # Target point (u, v) seen by each pixel: (u, v, 1) ~ inv([r1 r2 t]) (x, y, 1).
    inv_h = np.linalg.inv(np.column_stack([R[:, 0], R[:, 1], t]))
    height, width = rays.shape[:2]
    reflect, depth = np.empty((height, width)), np.empty((height, width))
    band = max(2, _BAND_PIXELS // width)
    for r0 in range(0, height, band):
        r1 = min(height, r0 + band)
        h0, h1 = max(0, r0 - 1), min(height, r1 + 1)  # one row beyond the band each side, for the gradient
        hom = rays[h0:h1] @ inv_h.T
        if np.any(hom[..., 2] <= 0):
            raise ValueError(
                "the target's plane does not fill the view in front of the camera (horizon in view)"
            )
        u, v = hom[..., 0] / hom[..., 2], hom[..., 1] / hom[..., 2]
        inside = slice(r0 - h0, r1 - h0)
        du_dy, du_dx = (np.asarray(g)[inside].ravel() for g in np.gradient(u))
        dv_dy, dv_dx = (np.asarray(g)[inside].ravel() for g in np.gradient(v))
        u, v = u[inside], v[inside]
        depth[r0:r1] = (R[2, 0] * u + R[2, 1] * v) + t[2]
        band_reflect = _band_reflectance(
            u.ravel(), v.ravel(), du_dx, du_dy, dv_dx, dv_dy, face, cell_mm, sigma_px
        )
        reflect[r0:r1] = band_reflect.reshape(r1 - r0, width)
    return reflect, depth
