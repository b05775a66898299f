"""Exact pixel coverage of blurred straight edges, and the crossed-groove land map built from them.

A pixel's value is the average over its unit square of the scene convolved with the optical PSF.
For a straight edge and a Gaussian PSF the blurred scene depends only on the signed distance ``s``
to the edge line: ``Phi(s / sigma)``. Projected onto the edge normal ``(cos phi, sin phi)``, the
uniform pixel square becomes a trapezoid (the convolution of two uniform densities of widths
``a = |cos phi|`` and ``b = |sin phi|``), so the pixel value is a second difference of the second
antiderivative of ``Phi`` (see ``box_step``). Nothing is sampled: edge positions are not quantised.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
from scipy.special import chndtr, ndtr

FloatArray = npt.NDArray[np.float64]
Float32Array = npt.NDArray[np.float32]

__all__ = ["box_step", "box_step_sorted", "cutoff_px", "edge_coverage", "land_fraction", "line_distance"]

_SMALL_WIDTH = 1e-5
"""Below this narrower trapezoid width the limit form is used (error < 1e-11, see ``box_step``)."""

_SQRT_2PI = float(np.sqrt(2.0 * np.pi))


def _pdf(x: FloatArray) -> FloatArray:
    return np.asarray(np.exp(-0.5 * x * x) / _SQRT_2PI)


def _phi1(x: FloatArray) -> FloatArray:
    """First antiderivative of the normal CDF: ``x Phi(x) + phi(x)``."""
    return np.asarray(x * ndtr(x) + _pdf(x))


def _phi2(x: FloatArray) -> FloatArray:
    """Second antiderivative of the normal CDF: ``((x^2 + 1) Phi(x) + x phi(x)) / 2``."""
    return np.asarray(0.5 * ((x * x + 1.0) * ndtr(x) + x * _pdf(x)))


def cutoff_px(sigma_px: float) -> float:
    """Distance from an edge beyond which a pixel is on one side to within 1e-13, px."""
    return 7.5 * sigma_px + 1.0


def box_step(d: npt.ArrayLike, cos_abs: npt.ArrayLike, sin_abs: npt.ArrayLike, sigma_px: float) -> FloatArray:
    """Fraction of a unit pixel on the positive side of a Gaussian-blurred straight edge.

    Parameters
    ----------
    d : array_like
        Signed distance of the pixel centre to the edge line, px (positive side -> 1).
    cos_abs, sin_abs : array_like
        ``|cos phi|`` and ``|sin phi|`` of the edge normal's image direction (broadcast with ``d``).
    sigma_px : float
        Standard deviation of the Gaussian blur, px; 0 means no blur (pure area coverage).

    Returns
    -------
    numpy.ndarray
        The average of ``Phi((d + t) / sigma)`` over the pixel square, in [0, 1], shape of the
        broadcast inputs.

    Notes
    -----
    With ``a >= b`` the trapezoid widths and ``G`` the second antiderivative of ``Phi``::

        value = sigma^2 / (a b) [G((d + (a+b)/2)/s) - G((d + (a-b)/2)/s)
                                 - G((d - (a-b)/2)/s) + G((d - (a+b)/2)/s)]

    For ``b -> 0`` this tends to ``sigma / a [G1((d + a/2)/s) - G1((d - a/2)/s)]`` with ``G1`` the
    first antiderivative, used below ``b = 1e-5``. Only non-positive distances are evaluated (the
    value for ``d > 0`` is ``1 - value(-d)``), where ``G`` is small, so cancellation costs less than
    1e-11 in absolute terms. With ``sigma = 0``, ``G`` becomes the ramp squared over two.
    """
    d_arr, ca, sa = np.broadcast_arrays(
        np.asarray(d, dtype=np.float64), np.asarray(cos_abs, np.float64), np.asarray(sin_abs, np.float64)
    )
    return box_step_sorted(d_arr, np.maximum(ca, sa), np.minimum(ca, sa), sigma_px)


def box_step_sorted(d_arr: FloatArray, a: FloatArray, b: FloatArray, sigma_px: float) -> FloatArray:
    """``box_step`` for same-shaped float64 arrays with the widths sorted already: ``a >= b`` (the larger
    and the smaller of ``|cos phi|``, ``|sin phi|``); what a caller that knows them per pixel evaluates."""
    s = -np.abs(d_arr)
    small = b < _SMALL_WIDTH
    if not small.any():  # the usual case: no masks to gather and scatter through
        low = _trapezoid(s, a, b, sigma_px)
    else:
        low = np.empty_like(s)
        wide = ~small
        if wide.any():
            low[wide] = _trapezoid(s[wide], a[wide], b[wide], sigma_px)
        low[small] = _rectangle(s[small], a[small], sigma_px)
    np.clip(low, 0.0, 0.5, out=low)
    return np.asarray(np.where(d_arr > 0.0, 1.0 - low, low))


def _trapezoid(s: FloatArray, a: FloatArray, b: FloatArray, sigma_px: float) -> FloatArray:
    """``box_step`` for ``s <= 0`` and ``b >= 1e-5``: second difference of ``G``."""
    if sigma_px > 0.0:
        x = s / sigma_px
        hp = (a + b) / (2.0 * sigma_px)
        hm = (a - b) / (2.0 * sigma_px)
        return np.asarray(
            (sigma_px * sigma_px / (a * b)) * (_phi2(x + hp) - _phi2(x + hm) - _phi2(x - hm) + _phi2(x - hp))
        )

    def ramp2(t: FloatArray) -> FloatArray:
        return np.asarray(0.5 * np.maximum(t, 0.0) ** 2)

    hp, hm = (a + b) / 2.0, (a - b) / 2.0
    return np.asarray((ramp2(s + hp) - ramp2(s + hm) - ramp2(s - hm) + ramp2(s - hp)) / (a * b))


def _rectangle(s: FloatArray, a: FloatArray, sigma_px: float) -> FloatArray:
    """``box_step`` for ``s <= 0`` and ``b -> 0``: first difference of ``G1``."""
    if sigma_px > 0.0:
        x = s / sigma_px
        ha = a / (2.0 * sigma_px)
        return np.asarray((sigma_px / a) * (_phi1(x + ha) - _phi1(x - ha)))
    return np.asarray((np.maximum(s + a / 2.0, 0.0) - np.maximum(s - a / 2.0, 0.0)) / a)


def line_distance(
    line: npt.ArrayLike, shape: tuple[int, int], box: tuple[slice, slice] | None = None
) -> FloatArray:
    """Signed distance ``a x + b y - c`` of pixel centres to a normalised line, px.

    Over the whole image of shape ``shape``, or over the sub-image ``box`` (row slice, column slice).
    """
    a, b, c = (float(v) for v in np.asarray(line, dtype=np.float64))
    rows, cols = box if box is not None else (slice(0, shape[0]), slice(0, shape[1]))
    xs = np.arange(cols.start, cols.stop, dtype=np.float64)
    ys = np.arange(rows.start, rows.stop, dtype=np.float64)
    return np.asarray(a * xs[None, :] + (b * ys[:, None] - c))


def edge_coverage(line: npt.ArrayLike, shape: tuple[int, int], sigma_px: float) -> FloatArray:
    """``box_step`` of one straight edge over a whole image, shape ``shape``.

    Pixels farther than ``cutoff_px`` from the line are 0 or 1 by side; ``box_step`` is evaluated
    only in the band along the line (a few rows per column, or columns per row).
    """
    a, b, c = (float(v) for v in np.asarray(line, dtype=np.float64))
    height, width = shape
    steep = abs(a) > abs(b)  # near-vertical: scan rows instead of columns
    n_across, n_along = (width, height) if steep else (height, width)
    p, q = (b, a) if steep else (a, b)  # d = p * along + q * across - c
    along = np.arange(n_along, dtype=np.float64)
    across = np.arange(n_across, dtype=np.float64)
    crossing = (c - p * along) / q  # where d = 0, per scan line
    compare = np.greater if q > 0 else np.less
    out = compare.outer(across, crossing).astype(np.float64)  # (n_across, n_along): d > 0
    half = cutoff_px(sigma_px) / abs(q)
    first = np.floor(crossing - half).astype(np.intp)
    idx_across = first[None, :] + np.arange(int(np.ceil(2 * half)) + 2)[:, None]
    idx_along = np.broadcast_to(np.arange(n_along), idx_across.shape)
    inside = (idx_across >= 0) & (idx_across < n_across)
    ia, il = idx_across[inside], idx_along[inside]
    out[ia, il] = box_step(p * il + q * ia - c, abs(a), abs(b), sigma_px)
    return np.asarray(out.T if steep else out)


# (line index, side) of the two boundary lines of each land: lines are top, bottom, left, right with
# normals toward +v, +v, +u, +u; a land lies on the negative side of top/left, positive of bottom/right.
_LANDS: tuple[tuple[tuple[int, int], tuple[int, int]], ...] = (
    ((0, -1), (2, -1)),  # top-left
    ((0, -1), (3, +1)),  # top-right
    ((1, +1), (3, +1)),  # bottom-right
    ((1, +1), (2, -1)),  # bottom-left
)


def land_fraction(
    lines: npt.ArrayLike,
    shape: tuple[int, int],
    *,
    sigma_px: float,
    corner_radius_px: Sequence[float],
) -> FloatArray:
    """Fraction of each pixel covered by bare land (1) rather than groove (0), blurred.

    Parameters
    ----------
    lines : array_like, shape (4, 3)
        The groove edges ``a x + b y = c`` (``a^2 + b^2 = 1``), px, ordered top, bottom, left, right,
        normals pointing toward increasing v (top, bottom) and increasing u (left, right).
    shape : (int, int)
        Image shape ``(height, width)``.
    sigma_px : float
        Gaussian blur, px.
    corner_radius_px : sequence of 4 float
        Radius of the rounded corner of each land at the crossing, px, ordered top-left, top-right,
        bottom-right, bottom-left (the order of the truth corners).

    Returns
    -------
    numpy.ndarray, shape ``shape``, float64
        Land coverage in [0, 1].

    Notes
    -----
    A land with sharp corner is the product of its two half-plane coverages ``S1 S2`` (exact far from
    the corner, and exact at the corner for pixel-aligned edges since the blur is separable); the four
    sharp lands sum to ``(1 - horizontal band)(1 - vertical band)``. The rounding removes the notch
    between the corner and the arc: with ``S1r, S2r`` the coverages of the lines moved ``r`` into the
    land and ``Sa`` the blurred disc of radius ``r`` tangent to both edges (a non-central chi-square
    CDF, the pixel box taken as a Gaussian of variance 1/12),

        land = S1 S2 - (S1 - S1r)(S2 - S2r) + Sa (1 - S1r)(1 - S2r),

    i.e. the sharp quadrant minus the r x r corner square plus the quarter disc. It is continuous,
    reduces to ``S2`` (``S1``) beyond ``r`` plus the blur cut-off from the corner along edge 2 (1),
    and approximates the blurred arc near the crossing (where no truth is claimed) while keeping the
    area removed close to the notch's ``r^2 (1 - pi/4)``.
    """
    lines_arr = np.asarray(lines, dtype=np.float64).reshape(4, 3)
    cover = [edge_coverage(line, shape, sigma_px) for line in lines_arr]
    # Sum of the four sharp lands = (1 - horizontal band)(1 - vertical band).
    total = (1.0 - cover[0] + cover[1]) * (1.0 - cover[2] + cover[3])
    cut = cutoff_px(sigma_px)
    for ((i, si), (j, sj)), radius in zip(_LANDS, corner_radius_px, strict=True):
        r = float(radius)
        box = _zone_box(lines_arr[i] * si, lines_arr[j] * sj, -cut, r + cut, shape) if r > 0.0 else None
        if box is None:
            continue
        d1, d2 = si * line_distance(lines_arr[i], shape, box), sj * line_distance(lines_arr[j], shape, box)
        zone = (d1 > -cut) & (d2 > -cut) & (d1 < r + cut) & (d2 < r + cut)
        s1 = cover[i][box][zone] if si > 0 else 1.0 - cover[i][box][zone]
        s2 = cover[j][box][zone] if sj > 0 else 1.0 - cover[j][box][zone]
        n1, n2 = si * lines_arr[i, :2], sj * lines_arr[j, :2]
        sub = total[box]
        sub[zone] += _corner_delta(d1[zone], d2[zone], s1, s2, n1, n2, r=r, sigma_px=sigma_px)
    return np.asarray(np.clip(total, 0.0, 1.0))


def _zone_box(
    line1: FloatArray, line2: FloatArray, lo: float, hi: float, shape: tuple[int, int]
) -> tuple[slice, slice] | None:
    """Pixel box around ``lo < d1, d2 < hi`` (``d = a x + b y - c`` for each line), or None if off-image."""
    m = np.array([line1[:2], line2[:2]])
    pts = np.array([np.linalg.solve(m, [p + line1[2], q + line2[2]]) for p in (lo, hi) for q in (lo, hi)])
    x0, y0 = np.floor(pts.min(axis=0)).astype(int) - 1
    x1, y1 = np.ceil(pts.max(axis=0)).astype(int) + 2
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, shape[1]), min(y1, shape[0])
    if x0 >= x1 or y0 >= y1:
        return None
    return slice(y0, y1), slice(x0, x1)


def _corner_delta(
    d1: FloatArray,
    d2: FloatArray,
    s1: FloatArray,
    s2: FloatArray,
    n1: FloatArray,
    n2: FloatArray,
    *,
    r: float,
    sigma_px: float,
) -> FloatArray:
    """Rounded minus sharp land coverage near a corner of radius ``r`` px (see ``land_fraction``)."""
    s1r = box_step(d1 - r, abs(n1[0]), abs(n1[1]), sigma_px)
    s2r = box_step(d2 - r, abs(n2[0]), abs(n2[1]), sigma_px)
    # The disc of radius r centred r inside both edges, blurred: P(|p + noise - centre| < r) is a
    # non-central chi-square CDF; the pixel box is approximated by a Gaussian of variance 1/12.
    var = sigma_px * sigma_px + 1.0 / 12.0
    rho2 = (d1 - r) ** 2 + (d2 - r) ** 2
    reach = 8.0 * np.sqrt(var)
    arc = (rho2 < r * r).astype(np.float64)
    ring = (rho2 > max(r - reach, 0.0) ** 2) & (rho2 < (r + reach) ** 2)
    arc[ring] = chndtr(r * r / var, 2.0, rho2[ring] / var)
    return np.asarray(arc * (1.0 - s1r) * (1.0 - s2r) - (s1 - s1r) * (s2 - s2r))
