"""Precise mode, stage 1: the coarse cross and the illumination (see ``_precise``).

The rotation from the fourfold gradient-angle mean, then each groove as the dark band of an intensity
profile projected along the groove on a 4x reduced image: a pixel or two, any rotation within the
mode's range, the crossing anywhere. Over the lands around it, the illumination (vignetting, light
gradient) as a smooth polynomial, so that the fine stage can divide it out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import cv2
import numpy as np
import numpy.typing as npt
from numpy.polynomial.polynomial import polyval2d

from station.vision._edges import EDGES, Edge
from station.vision._errors import EdgeNotFoundError, describe_missing, rotated_too_far
from station.vision._image import Gray8
from station.vision._kernels import compiled
from station.vision._orientation import dominant_rotation_deg
from station.vision._params import MeasureParams

FloatArray = npt.NDArray[np.float64]

COARSE_SCALE = 4


def fast_median(a: FloatArray) -> float:
    """The (upper) median: one partition, without np.median's overhead on small arrays."""
    k = a.size // 2
    return float(np.partition(a, k)[k])


@dataclass(frozen=True)
class CoarseCross:
    """The cross found on the reduced image, in full-resolution px.

    ``theta``: rotation (rad; the horizontal groove runs along (cos, sin)); ``edges``: per edge, its
    signed offset from the image centre along the edge's normal (px).
    """

    theta: float
    offsets: dict[Edge, float]
    illumination: Illumination | None = None


#: Exponents (i, j) of x^i y^j in the flat-field polynomial (degree 4: radial falloff and its tilt).
_FLAT_DEGREE = 4
_FLAT_TERMS = tuple((i, d - i) for d in range(_FLAT_DEGREE + 1) for i in range(d + 1))


def _normalised(x: FloatArray, y: FloatArray, shape: tuple[int, int]) -> tuple[FloatArray, FloatArray]:
    """Image coordinates scaled to -1..1 over the frame (the flat-field polynomial's variables)."""
    h, w = shape
    return (x - (w - 1) / 2.0) / (w / 2.0), (y - (h - 1) / 2.0) / (h / 2.0)


def _flat_basis(x: FloatArray, y: FloatArray, shape: tuple[int, int]) -> FloatArray:
    """Polynomial terms of normalised coordinates (-1..1 over the frame), stacked on the last axis."""
    xn, yn = _normalised(x, y, shape)
    # powers by repeated products: numpy's generic pow is ~20x slower than a multiply
    xp, yp = [np.ones_like(xn), xn], [np.ones_like(yn), yn]
    for _ in range(_FLAT_DEGREE - 1):
        xp.append(xp[-1] * xn)
        yp.append(yp[-1] * yn)
    return np.stack([xp[i] * yp[j] for i, j in _FLAT_TERMS], axis=-1)


@lru_cache(maxsize=8)
def _power_tables(shape: tuple[int, int]) -> tuple[FloatArray, FloatArray]:
    """Powers 0..degree of every column's and row's normalised coordinate: (d+1, w) and (d+1, h)."""
    h, w = shape
    xn, yn = _normalised(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64), shape)
    xp = np.stack([xn**i for i in range(_FLAT_DEGREE + 1)])
    yp = np.stack([yn**i for i in range(_FLAT_DEGREE + 1)])
    xp.setflags(write=False)
    yp.setflags(write=False)
    return xp, yp


@lru_cache(maxsize=8)
def _row_coordinate(shape: tuple[int, int]) -> FloatArray:
    """Every row's normalised coordinate, (h,) C-contiguous (``_power_tables``'s row 1 of y)."""
    yn = np.ascontiguousarray(_power_tables(shape)[1][1])
    yn.setflags(write=False)
    return yn


@lru_cache(maxsize=8)
def _small_basis(small_shape: tuple[int, int], shape: tuple[int, int], scale: int) -> FloatArray:
    """Flat-field polynomial terms at the reduced image's pixel centres, (terms, sh*sw)."""
    xf, yf = _centred_grid(small_shape, shape, scale)
    h, w = shape
    basis = np.ascontiguousarray(
        _flat_basis((xf + (w - 1) / 2.0).ravel(), (yf + (h - 1) / 2.0).ravel(), shape).T
    )
    basis.setflags(write=False)
    return basis


@dataclass(frozen=True)
class Illumination:
    """The relative illumination over the frame: a polynomial of the image coordinates (mean 1 on
    the lands). ``at(x, y)`` evaluates it anywhere (arrays of any shape)."""

    coef: FloatArray
    shape: tuple[int, int]

    def at(self, x: FloatArray, y: FloatArray) -> FloatArray:
        """The illumination at image points (any shape), by Horner's scheme in x and y."""
        xn, yn = _normalised(x, y, self.shape)
        return np.asarray(polyval2d(xn, yn, self._grid), dtype=np.float64)

    def at_pixels(self, x: npt.NDArray[np.intp], y: npt.NDArray[np.intp]) -> FloatArray:
        """The illumination at whole pixels (1-D index arrays inside the frame): the same polynomial
        as ``at`` from tables of each column's and row's powers, without evaluating them again."""
        # Horner's scheme in y with each column's coefficients: 1-D gathers and products only
        coef = self._column_coef
        yn = _power_tables(self.shape)[1][1][y]
        value = coef[_FLAT_DEGREE][x]
        for j in range(_FLAT_DEGREE - 1, -1, -1):
            value = value * yn + coef[j][x]
        return np.asarray(value, np.float64)

    def pixel_tables(self) -> tuple[FloatArray, FloatArray]:
        """What ``at_pixels`` evaluates, for the compiled kernel: per column x the coefficients of
        y^0..y^d, (d+1, w), and every row's normalised y, (h,), both C-contiguous float64."""
        return self._column_coef, _row_coordinate(self.shape)

    @cached_property
    def _column_coef(self) -> FloatArray:
        """(d+1, w): per image column x, the coefficients of y^0..y^d: sum_i coef[i, j] xn^i."""
        return np.ascontiguousarray(self._grid.T @ _power_tables(self.shape)[0], np.float64)

    @cached_property
    def _grid(self) -> FloatArray:
        grid = np.zeros((_FLAT_DEGREE + 1, _FLAT_DEGREE + 1))
        for (i, j), value in zip(_FLAT_TERMS, self.coef, strict=True):
            grid[i, j] = value
        return grid


def _solve_normal(At: FloatArray, values: FloatArray) -> FloatArray:
    """Least squares by the normal equations (At: (terms, points)), solved by OpenCV's Cholesky
    (numpy's general solver costs more in checks than in arithmetic at this size)."""
    ok, coef = cv2.solve(At @ At.T, (At @ values)[:, None], flags=cv2.DECOMP_CHOLESKY)
    if not ok:  # not positive definite (degenerate lands): the general solver decides
        return np.asarray(np.linalg.solve(At @ At.T, At @ values), np.float64)
    return np.asarray(coef, np.float64).ravel()


def fit_illumination(
    small: npt.NDArray[np.float32], land: npt.NDArray[np.bool_], shape: tuple[int, int], *, scale: int
) -> Illumination | None:
    """The relative illumination (vignetting, light gradient) over the frame, fitted on the lands.

    A degree-4 polynomial in the image coordinates is fitted to the land pixels of the reduced image
    (every fourth one is plenty), refitted once without scratches and glints (beyond 3 MAD) and
    normalised to mean 1 over the lands. None when too few land pixels are seen or the fit runs wild.
    By the compiled kernel when selected (``_kernels``), else numpy (the reference).
    """
    sh, sw = small.shape
    basis = _small_basis((sh, sw), shape, scale)
    ck = compiled()
    if ck is not None:
        coef = np.empty(len(_FLAT_TERMS))
        status = ck.illumination(
            np.ascontiguousarray(small, np.float32), np.ascontiguousarray(land, np.bool_), basis, coef
        )
        if status >= 0:  # else singular normal equations: numpy's general solver decides, below
            return Illumination(coef, shape) if status else None
    idx = np.flatnonzero(land.ravel())[::4]
    if idx.size < 10 * len(_FLAT_TERMS):
        return None
    At = np.take(basis, idx, axis=1)  # (terms, points): the normal equations are row products
    values = small.ravel()[idx].astype(np.float64)
    coef = _solve_normal(At, values)
    resid = values - coef @ At
    mad = fast_median(np.abs(resid - fast_median(resid)))
    keep = np.abs(resid) <= 3.0 * 1.4826 * max(mad, 1e-6)
    Akt = At[:, keep]
    coef = _solve_normal(Akt, values[keep])
    fitted = coef @ Akt
    level = float(fitted.mean())
    if level <= 0 or float(fitted.min()) <= 0.05 * level:
        return None  # the fit ran wild (too few lands in view): do without
    return Illumination(np.asarray(coef / level, np.float64), shape)


def _band_edges(profile: FloatArray, counts: FloatArray) -> tuple[int, int]:
    """Indices (falling, rising) of the darkest band's two edges in a projected profile. By the
    compiled kernel when selected (``_kernels``), else numpy (the reference)."""
    ck = compiled()
    if ck is not None:
        status, fall, rise = ck.band_edges(
            np.ascontiguousarray(profile, np.float64), np.ascontiguousarray(counts, np.float64)
        )
        if status == 0:
            return fall, rise
        if status == 1:
            raise ValueError("no dark band stands out of the profile's noise")
    valid = counts >= max(3.0, 0.2 * float(counts.max()))
    idx = np.flatnonzero(valid)
    lo, hi = int(idx[0]), int(idx[-1])
    p = profile[lo : hi + 1]
    smooth = np.convolve(p, np.ones(3) / 3.0, mode="same")
    smooth[0], smooth[-1] = p[0], p[-1]
    d = np.diff(smooth)
    # the groove: the pair (strongest fall, strongest rise after it) with the deepest dark band between
    # a real groove's walls stand far above the profile's noise (pure noise has no such band)
    noise = 1.4826 * fast_median(np.abs(d - fast_median(d)))
    fall = int(np.argmin(d))
    rise_candidates = d[fall + 1 :]
    if rise_candidates.size == 0:
        raise ValueError("no rising edge after the falling one")
    rise = fall + 1 + int(np.argmax(rise_candidates))
    best_fall = fall
    # check the alternative: strongest rise first, strongest fall before it
    rise2 = int(np.argmax(d))
    if rise2 > 0:
        fall2 = int(np.argmin(d[:rise2]))
        depth1 = d[rise] - d[fall]
        depth2 = d[rise2] - d[fall2]
        if depth2 > depth1:
            best_fall, rise = fall2, rise2
    if min(-d[best_fall], d[rise]) < max(8.0 * noise, 2.0):
        raise ValueError("no dark band stands out of the profile's noise")
    return lo + best_fall, lo + rise


@lru_cache(maxsize=8)
def _centred_grid(
    small_shape: tuple[int, int], shape: tuple[int, int], scale: int = COARSE_SCALE
) -> tuple[FloatArray, FloatArray]:
    """Full-resolution coordinates (relative to the image centre) of the reduced image's pixel centres.

    Reduced pixel (i, j) covers full-res [s*j - 0.5, s*j + s - 0.5]: its centre is s*j + (s - 1)/2.
    """
    s = scale
    sh, sw = small_shape
    h, w = shape
    ys, xs = np.mgrid[0:sh, 0:sw].astype(np.float64)
    xf = xs * s + (s - 1) / 2.0 - (w - 1) / 2.0
    yf = ys * s + (s - 1) / 2.0 - (h - 1) / 2.0
    xf.setflags(write=False)
    yf.setflags(write=False)
    return xf, yf


def reduce_4x(gray: Gray8) -> npt.NDArray[np.float32]:
    """The image reduced 4x by area averaging (reduced pixel (i, j) is the mean of full-res rows
    4i..4i+3, columns 4j..4j+3; a remainder of fewer than 4 rows or columns is left out).

    Two 2x steps on 8 bits: OpenCV's 2x area reduction is vectorised, its 4x one is not (7x slower).
    Each step rounds to whole DN, well below the noise of a coarse estimate.
    """
    s = COARSE_SCALE
    h, w = gray.shape
    sh, sw = h // s, w // s
    half = cv2.resize(gray[: sh * s, : sw * s], (2 * sw, 2 * sh), interpolation=cv2.INTER_AREA)
    small = cv2.resize(half, (sw, sh), interpolation=cv2.INTER_AREA)
    return np.asarray(small, np.float32)


Projection = tuple[int, FloatArray, FloatArray]


def _projections(
    small: npt.NDArray[np.float32], shape: tuple[int, int], theta: float
) -> tuple[FloatArray, FloatArray, tuple[Projection, Projection]]:
    """The reduced image projected along the two grooves: per reduced pixel its coordinates u (along
    the horizontal groove) and v (along the vertical one), full-resolution px from the image centre;
    then for v and for u the pixels binned by coordinate in reduced px (bin b: floor(coord / scale)
    = base + b), each bin's count and sum. By the compiled kernel when selected (``_kernels``), else
    numpy (the reference)."""
    h, w = shape
    s = COARSE_SCALE
    ck = compiled()
    if ck is not None:
        u, v = np.empty(small.shape), np.empty(small.shape)
        cap = math.ceil(math.hypot(h, w) / s) + 4
        counts, sums = np.empty((2, cap)), np.empty((2, cap))
        base_v, bins_v, base_u, bins_u = ck.project(
            np.ascontiguousarray(small, np.float32), h, w, s, theta, u, v, counts, sums
        )
        return (
            u,
            v,
            (
                (int(base_v), counts[0, :bins_v], sums[0, :bins_v]),
                (int(base_u), counts[1, :bins_u], sums[1, :bins_u]),
            ),
        )
    xf, yf = _centred_grid(small.shape, (h, w))
    c, sn = math.cos(theta), math.sin(theta)
    u = xf * c + yf * sn  # along the horizontal groove
    v = -xf * sn + yf * c  # along the vertical groove
    values = small.ravel().astype(np.float64)
    out: list[Projection] = []
    for coord in (v, u):
        q = coord.ravel() / s
        base = math.floor(float(q.min()))
        bins = (q - base).astype(np.intp)  # non-negative: truncation is floor
        sums = np.asarray(np.bincount(bins, weights=values), np.float64)
        out.append((base, np.bincount(bins).astype(np.float64), sums))
    return u, v, (out[0], out[1])


def coarse_cross(gray: Gray8, params: MeasureParams) -> CoarseCross:
    """Find the two grooves roughly (to about a pixel) on a reduced image."""
    h, w = gray.shape
    s = COARSE_SCALE
    small = reduce_4x(gray)
    rotation_deg, strength = dominant_rotation_deg(small)
    max_rot = params.rotation_limit_deg
    if strength < 0.05:
        raise EdgeNotFoundError(
            "found 0 of 4 edges: no straight edges in the image (is the crossed-groove artifact in view "
            "and in focus?)"
        )
    if abs(rotation_deg) > max_rot:
        raise rotated_too_far(rotation_deg, max_rot)
    theta = math.radians(rotation_deg)
    u, v, projections = _projections(small, (h, w), theta)
    offsets: dict[Edge, float] = {}
    names: tuple[tuple[Edge, Edge], tuple[Edge, Edge]] = (("top", "bottom"), ("left", "right"))
    for (base, counts, sums), (falling, rising) in zip(projections, names, strict=True):
        profile = sums / np.maximum(counts, 1.0)
        try:
            i_fall, i_rise = _band_edges(profile, counts)
        except ValueError:
            continue
        # diff index i sits between bins i and i+1: boundary at bin value i + 1 -> coordinate (i+1+base)*s
        offsets[falling] = (i_fall + 1 + base) * s
        offsets[rising] = (i_rise + 1 + base) * s
    if len(offsets) < 4:
        raise EdgeNotFoundError(
            describe_missing({e: "no dark band across the frame" for e in EDGES if e not in offsets}),
            found=tuple(offsets),
        )
    illumination = None
    if params.flat_field:
        margin = 2.0 * s
        v_mid = (offsets["top"] + offsets["bottom"]) / 2.0
        v_half = (offsets["bottom"] - offsets["top"]) / 2.0 + margin
        u_mid = (offsets["left"] + offsets["right"]) / 2.0
        u_half = (offsets["right"] - offsets["left"]) / 2.0 + margin
        # the illumination is smooth: fit it on the image reduced once more (2x2 of the reduced pixels)
        sh2, sw2 = small.shape[0] // 2, small.shape[1] // 2
        tiny = np.asarray(
            cv2.resize(small[: 2 * sh2, : 2 * sw2], (sw2, sh2), interpolation=cv2.INTER_AREA), np.float32
        )
        ck = compiled()
        if ck is not None:  # the same mask in one pass (``_kernels``)
            land2 = np.empty((sh2, sw2), np.bool_)
            ck.lands(u, v, v_mid, v_half, u_mid, u_half, land2)
        else:
            land = (np.abs(v - v_mid) > v_half) & (np.abs(u - u_mid) > u_half)
            land2 = land[: 2 * sh2 : 2, : 2 * sw2 : 2] & land[1 : 2 * sh2 : 2, 1 : 2 * sw2 : 2]
        illumination = fit_illumination(tiny, land2, (h, w), scale=2 * s)
    return CoarseCross(theta, offsets, illumination)
