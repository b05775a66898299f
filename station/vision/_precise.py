"""Precise mode: the seed's structure (four edges -> four lines -> vertices -> projective transform),
with the stages that limit its accuracy replaced (accuracy.md).

1. **Coarse cross** (replaces filter + Prewitt + threshold + TestBox): the rotation from the fourfold
   gradient-angle mean, then each groove as the dark band of an intensity profile projected along the
   groove on a 4x reduced image. Any rotation within the mode's range, the crossing anywhere.
2. **Sub-pixel edge points** (replaces the 3x3 raw-intensity moment): in a band around the predicted
   edge, for every column (horizontal edges) or row (vertical edges), the centroid of the intensity's
   first differences over a window exactly symmetric about the current estimate. The first difference
   of a pixel-integrated edge is the edge's line-spread function convolved with two unit boxes; its
   samples at unit spacing have a centroid equal to the continuous one (the boxes' spectra vanish at the
   sampling harmonics), so the estimator has no pixel-locking bias for any blur; a constant background
   slope cancels in the symmetric window. Re-centring on the fitted line (``passes``) removes the
   window's offset.
3. **Robust orthogonal line fit** (replaces y-on-x regression with correlation-driven removal):
   residuals are taken from the previous pass's line, points beyond ``outlier_sigma`` robust
   (1.4826 MAD) sigmas are dropped, and the rest fitted by total least squares, twice; glints,
   scratches and salt-and-pepper give off-line points or weak profiles, both rejected. The rounded
   land corners are excluded by a margin around the crossing. The coarse stage lives in ``_coarse``.
4. Optional lens-distortion correction: the image is resampled to an ideal pinhole camera with an
   OpenCV camera model before anything else (results in undistorted pixel coordinates).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._coarse import CoarseCross, Illumination, coarse_cross, fast_median
from station.vision._edges import EDGES, Edge
from station.vision._errors import EdgeNotFoundError, describe_missing
from station.vision._geometry import VERTICAL, Line, intersect, normal_form
from station.vision._image import Gray8
from station.vision._params import MeasureParams
from station.vision._result import EdgeFit

FloatArray = npt.NDArray[np.float64]

#: Edges sampled together: the same orientation, profiles along the same image axis.
_GROUPS: tuple[tuple[Edge, Edge], ...] = (("top", "bottom"), ("left", "right"))
#: +1 where the intensity rises across the edge in the scan direction (+y or +x), -1 where it falls.
_POLARITY: dict[Edge, float] = {"top": -1.0, "bottom": 1.0, "left": -1.0, "right": 1.0}


@dataclass(frozen=True)
class _EdgeModel:
    """An edge as ``across = slope * along + intercept`` in image px (along = x for horizontal edges)."""

    slope: float
    intercept: float


def _initial_model(coarse: CoarseCross, edge: Edge, shape: tuple[int, int]) -> _EdgeModel:
    h, w = shape
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    c, s = math.cos(coarse.theta), math.sin(coarse.theta)
    off = coarse.offsets[edge]
    if edge in VERTICAL:
        # u = (x - cx) c + (y - cy) s = off  ->  x = cx + (off - (y - cy) s) / c
        return _EdgeModel(-s / c, cx + (off + cy * s) / c)
    # v = -(x - cx) s + (y - cy) c = off  ->  y = cy + (off + (x - cx) s) / c
    return _EdgeModel(s / c, cy + (off - cx * s) / c)


def _crossing_extent(models: dict[Edge, _EdgeModel]) -> dict[Edge, tuple[float, float]]:
    """Per edge: (along coordinate of the crossing's centre, half-width of the perpendicular groove)."""
    lines = {e: _line_of(m, vertical=e in VERTICAL) for e, m in models.items()}
    pts = np.array([intersect(lines[a], lines[b]) for a in ("top", "bottom") for b in ("left", "right")])
    out: dict[Edge, tuple[float, float]] = {}
    for edge in EDGES:
        along = pts[:, 1] if edge in VERTICAL else pts[:, 0]
        out[edge] = (float(along.mean()), float(along.max() - along.min()) / 2.0)
    return out


def _line_of(model: _EdgeModel, *, vertical: bool) -> Line:
    return normal_form(model.slope, model.intercept, vertical=vertical)


@lru_cache(maxsize=16)
def _ramp(n: int) -> npt.NDArray[np.float32]:
    """(1, n) from 0 to 1: linear interpolation weights across a window of n samples."""
    ramp = np.linspace(0.0, 1.0, n, dtype=np.float32)[None, :]
    ramp.setflags(write=False)
    return ramp


def _suppress_impulses(samples: npt.NDArray[np.float32], threshold: float) -> None:
    """Replace isolated impulses (salt-and-pepper, hot pixels) in profiles across an edge, in place.

    A clean blurred edge profile is monotonic, and the median of three neighbours leaves a monotonic
    sequence unchanged: only samples that differ from their 3-sample median by more than ``threshold``
    (DN) are replaced by it, so clean profiles are untouched and the estimator stays unbiased.
    """
    a, b, c = samples[:, :-2], samples[:, 1:-1], samples[:, 2:]
    med = np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))
    bad = np.abs(b - med) > threshold
    if bad.any():
        b[bad] = med[bad]


def _profile_points(
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32],
    *,
    vertical: bool,
    along: npt.NDArray[np.intp],
    mu: FloatArray,
    polarity: npt.NDArray[np.float32],
    half: int,
    impulse_dn: float,
    illumination: Illumination | None = None,
    with_spread: bool = True,
) -> tuple[npt.NDArray[np.bool_], FloatArray, FloatArray, FloatArray | None]:
    """Sub-pixel edge positions of many profiles at once (module docstring, step 2).

    Profile i runs across the edge at ``along[i]`` (a column for horizontal edges, a row for vertical
    ones), in a window of ``2 * half + 2`` samples about the predicted position ``mu[i]``; ``polarity``
    is +1 where the intensity rises along the scan. Profiles of several edges with the same orientation
    go in one call. Returns ``(inside, across, strength, spread)``: ``inside`` marks the profiles whose
    window fits in the image; the others are for those only: ``across`` the position (px),
    ``strength`` the window's summed first difference (the local contrast, DN), ``spread`` the second
    central moment of the differences (px^2).
    """
    h, w = img.shape
    n_across = w if vertical else h
    base = np.floor(mu).astype(np.intp) - half
    inside = (base >= 0) & (base + 2 * half + 1 < n_across)
    along, mu, base, polarity = along[inside], mu[inside], base[inside], polarity[inside]
    k = base[:, None] + np.arange(2 * half + 2)[None, :]
    flat = along[:, None] * w + k if vertical else k * w + along[:, None]
    samples = np.take(img, flat).astype(np.float32)
    if illumination is not None:
        # flat field: the illumination is smooth, linear over one window: divide the samples by it,
        # evaluated at the window's two ends
        ends = np.column_stack([base, base + 2 * half + 1]).astype(np.float64)
        a = np.broadcast_to(along[:, None].astype(np.float64), ends.shape)
        v = illumination.at(ends, a) if vertical else illumination.at(a, ends)
        ramp = _ramp(2 * half + 2)
        v32 = v.astype(np.float32)
        samples /= v32[:, :1] + (v32[:, 1:] - v32[:, :1]) * ramp
    _suppress_impulses(samples, impulse_dn)
    d = (samples[:, 1:] - samples[:, :-1]) * polarity[:, None]
    # positions relative to each window's first sample keep float32 exact to ~1e-6 px
    pos = np.arange(2 * half + 1, dtype=np.float32) + np.float32(0.5)
    mu_rel = (mu - base).astype(np.float32)
    weight = np.clip(np.float32(half + 0.5) - np.abs(pos[None, :] - mu_rel[:, None]), 0.0, 1.0)
    wd = weight * d
    strength = wd.sum(axis=1, dtype=np.float64)
    safe = np.where(strength > 0, strength, 1.0)
    rel = (wd @ pos).astype(np.float64) / safe
    spread = (
        ((wd * (pos[None, :] - rel[:, None].astype(np.float32)) ** 2).sum(axis=1) / safe)
        if with_spread
        else None
    )
    return inside, base + rel, strength, spread


def _tls(x: FloatArray, y: FloatArray) -> Line:
    """Total-least-squares line through points (closed form for 2-D: the principal axis)."""
    n = x.size
    mx, my = float(x.sum()) / n, float(y.sum()) / n
    dx, dy = x - mx, y - my
    sxx, syy, sxy = float(dx @ dx), float(dy @ dy), float(dx @ dy)
    phi = 0.5 * math.atan2(2.0 * sxy, sxx - syy)  # direction of the line
    nx, ny = -math.sin(phi), math.cos(phi)
    return (nx, ny, nx * mx + ny * my)


def _robust_tls(
    x: FloatArray, y: FloatArray, prior: Line, outlier_sigma: float, *, rounds: int = 2
) -> tuple[Line, npt.NDArray[np.bool_], float]:
    """Orthogonal line fit with outliers rejected beyond ``outlier_sigma`` robust sigmas.

    Residuals are first taken from ``prior`` (the previous pass's line, close to the truth), so a
    cluster of glint points cannot drag the first estimate; the robust sigma is 1.4826 MAD.
    Returns (line, inliers, rms of the inliers' residuals).
    """
    a, b, c = prior
    resid = a * x + b * y - c
    inliers = np.ones(x.size, dtype=bool)
    line = prior
    for _ in range(rounds):
        r = resid[inliers]
        med = fast_median(r)
        sigma = max(1.4826 * fast_median(np.abs(r - med)), 1e-3)
        inliers = np.abs(resid - med) <= outlier_sigma * sigma
        if inliers.sum() < 3:
            raise ValueError("too few inliers")
        line = _tls(x[inliers], y[inliers])
        a, b, c = line
        resid = a * x + b * y - c
    ri = resid[inliers]
    rms = math.sqrt(float(ri @ ri) / ri.size)
    return line, inliers, rms


def _orient(line: Line, *, vertical: bool) -> Line:
    a, b, c = line
    if (vertical and a < 0) or (not vertical and b < 0):
        return (-a, -b, -c)
    return (a, b, c)


def _model_from_line(line: Line, *, vertical: bool) -> _EdgeModel:
    a, b, c = line
    if vertical:  # a x + b y = c -> x = (c - b y) / a
        return _EdgeModel(-b / a, c / a)
    return _EdgeModel(-a / b, c / b)


@lru_cache(maxsize=4)
def _undistort_maps(
    camera_matrix: tuple[float, ...], dist_coeffs: tuple[float, ...], shape: tuple[int, int]
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    K = np.asarray(camera_matrix, np.float64).reshape(3, 3)
    h, w = shape
    map1, map2 = cv2.initUndistortRectifyMap(K, np.asarray(dist_coeffs), None, K, (w, h), cv2.CV_32FC1)
    return np.asarray(map1, np.float32), np.asarray(map2, np.float32)


def undistort(img: npt.NDArray[np.float32], params: MeasureParams) -> npt.NDArray[np.float32]:
    """The image as an ideal pinhole camera with the same camera matrix would see it (no distortion).

    Straight edges become straight again; results are then in undistorted pixel coordinates.
    Bilinear resampling: a symmetric kernel moves no edge.
    """
    if params.camera_matrix is None:
        return img
    K = tuple(float(v) for row in params.camera_matrix for v in row)
    dist = tuple(float(v) for v in (params.dist_coeffs or []))
    h, w = img.shape
    map1, map2 = _undistort_maps(K, dist, (h, w))
    return np.asarray(
        cv2.remap(img, map1, map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE), np.float32
    )


def _fit_edge(
    edge: Edge,
    t: FloatArray,
    a: FloatArray,
    strength: FloatArray,
    spread: FloatArray | None,
    model: _EdgeModel,
    params: MeasureParams,
    *,
    half: int,
    last: bool,
) -> tuple[EdgeFit | None, _EdgeModel, float | None] | str:
    """One edge's line from its profiles: (fit on the last pass, new model, median spread), or the
    reason it was not found."""
    if t.size < params.min_edge_points:
        return (
            f"only {t.size} of its profiles fit inside the frame (at least {params.min_edge_points}): "
            "it runs too close to the border; keep the groove corners 10 px or more inside the frame"
        )
    contrast = fast_median(strength)
    if contrast < params.min_contrast_dn:
        return f"its contrast is {contrast:.1f} DN (at least {params.min_contrast_dn} DN)"
    good = strength > params.min_contrast_fraction * contrast
    good &= np.abs(a - (model.slope * t + model.intercept)) < (half / 2.0 if last else half - 2.0)
    if good.sum() < params.min_edge_points:
        return f"only {int(good.sum())} profiles show the edge"
    vertical = edge in VERTICAL
    x, y = (a[good], t[good]) if vertical else (t[good], a[good])
    try:
        line, inliers, rms = _robust_tls(
            x, y, _line_of(model, vertical=vertical), params.outlier_sigma, rounds=2 if last else 1
        )
    except ValueError:
        return "its points do not lie on a line"
    line = _orient(line, vertical=vertical)
    if last and rms > params.residual_limit_px:  # earlier passes only steer the windows
        return f"its points are not on a line (rms {rms:.2f} px)"
    fit = None
    if last:
        fit = EdgeFit(
            name=edge,
            line=line,
            segmented=int(t.size),
            used=int(inliers.sum()),
            removed=int(t.size - inliers.sum()),
            rms_px=rms,
            points=np.column_stack([x[inliers], y[inliers]]),
        )
    spread_median = fast_median(spread[good]) if spread is not None else None
    return fit, _model_from_line(line, vertical=vertical), spread_median


def precise_edges(gray: Gray8, params: MeasureParams) -> dict[Edge, EdgeFit]:
    """Four robust sub-pixel edge lines (module docstring); raises EdgeNotFoundError or GeometryError."""
    h, w = gray.shape
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32] = gray
    if params.camera_matrix is not None:
        img = undistort(gray.astype(np.float32), params)
        gray = np.clip(np.rint(img), 0, 255).astype(np.uint8)  # the coarse stage works on 8 bits
    coarse = coarse_cross(gray, params)
    models = {e: _initial_model(coarse, e, (h, w)) for e in EDGES}
    # the first pass steers from the coarse cross (a pixel or two off at the frame's ends): wide window
    half = params.window_px if params.window_px is not None else 8
    border = half + 2
    fits: dict[Edge, EdgeFit] = {}
    problems: dict[Edge, str] = {}
    for pass_no in range(params.passes):
        last = pass_no == params.passes - 1
        spreads: list[float] = []
        new_models: dict[Edge, _EdgeModel] = {}
        crossing = _crossing_extent(models)
        for group in _GROUPS:
            vertical = group[0] in VERTICAL
            length = h if vertical else w
            # passes before the last only steer the windows: every 8th profile is plenty; the last
            # takes every profile_step-th column (row)
            along_all = np.arange(border, length - border, params.profile_step if last else 8, dtype=np.intp)
            parts: list[tuple[Edge, npt.NDArray[np.intp], FloatArray]] = []
            for edge in group:
                centre_along, half_groove = crossing[edge]
                along = along_all[np.abs(along_all - centre_along) > half_groove + params.corner_margin_px]
                m = models[edge]
                parts.append((edge, along, m.slope * along + m.intercept))
            along_cat = np.concatenate([a for _, a, _ in parts])
            owner = np.concatenate([np.full(a.size, i) for i, (_, a, _) in enumerate(parts)])
            polarity = np.array([_POLARITY[e] for e, _, _ in parts], np.float32)[owner]
            inside, across, strength, spread = _profile_points(
                img,
                vertical=vertical,
                along=along_cat,
                mu=np.concatenate([mu for _, _, mu in parts]),
                polarity=polarity,
                half=half,
                impulse_dn=params.impulse_dn,
                illumination=coarse.illumination,  # vignetting would bias the profiles' centroids
                with_spread=not last,
            )
            owner = owner[inside]
            along_cat = along_cat[inside]
            for i, (edge, _, _) in enumerate(parts):
                sel = owner == i
                outcome = _fit_edge(
                    edge,
                    along_cat[sel].astype(np.float64),
                    across[sel],
                    strength[sel],
                    None if spread is None else spread[sel],
                    models[edge],
                    params,
                    half=half,
                    last=last,
                )
                if isinstance(outcome, str):
                    problems[edge] = outcome
                    continue
                fit, model, spread_median = outcome
                new_models[edge] = model
                if spread_median is not None:
                    spreads.append(spread_median)
                if fit is not None:
                    fits[edge] = fit
        if problems:
            raise EdgeNotFoundError(describe_missing(problems), found=tuple(new_models))
        models = new_models
        if params.window_px is None and spreads:
            # window half-width: window_sigmas line-spread sigmas + 1 px (spread includes the two unit
            # boxes of the first difference: 2/12 px^2)
            sigma = math.sqrt(max(fast_median(np.asarray(spreads)) - 1.0 / 6.0, 0.1))
            half = int(np.clip(math.ceil(params.window_sigmas * sigma) + 1, 3, 12))
            border = half + 2
    return fits
