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
   land corners are excluded by a margin around the crossing. The coarse stage lives in ``_coarse``, the
   line fit in ``_edge_fit``.
4. Optional lens-distortion correction: the image is resampled to an ideal pinhole camera with an
   OpenCV camera model before anything else (results in undistorted pixel coordinates).
"""

from __future__ import annotations

import math
from functools import lru_cache
from types import ModuleType

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._coarse import CoarseCross, Illumination, coarse_cross
from station.vision._edge_fit import (
    _POLARITY,
    _ROWS,
    _VERTICAL,
    FloatArray,
    _failure,
    _fit_edges,
    _Models,
    _Profiles,
)
from station.vision._edges import EDGES, Edge
from station.vision._errors import EdgeNotFoundError, describe_missing
from station.vision._image import Gray8
from station.vision._kernels import compiled
from station.vision._params import MeasureParams
from station.vision._result import EdgeFit


def _initial_models(coarse: CoarseCross, shape: tuple[int, int]) -> _Models:
    h, w = shape
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    c, s = math.cos(coarse.theta), math.sin(coarse.theta)
    off = np.array([coarse.offsets[e] for e in EDGES])
    # vertical: u = (x - cx) c + (y - cy) s = off  ->  x = cx + (off - (y - cy) s) / c
    # horizontal: v = -(x - cx) s + (y - cy) c = off  ->  y = cy + (off + (x - cx) s) / c
    slope = np.where(_VERTICAL, -s / c, s / c)
    intercept = np.where(_VERTICAL, cx + (off + cy * s) / c, cy + (off - cx * s) / c)
    return _Models(slope, intercept)


def _crossing_extent(models: _Models) -> tuple[FloatArray, FloatArray]:
    """Per edge: the along coordinate of the crossing's centre and the half-width of the perpendicular
    groove, from the four vertices of the models."""
    sh, ih = models.slope[:2, None], models.intercept[:2, None]  # y = sh x + ih
    sv, iv = models.slope[None, 2:], models.intercept[None, 2:]  # x = sv y + iv
    x = (sv * ih + iv) / (1.0 - sv * sh)  # (horizontal edge, vertical edge)
    y = sh * x + ih
    along = np.stack([x.ravel(), x.ravel(), y.ravel(), y.ravel()])  # per edge: its along coordinates
    return along.mean(axis=1), (along.max(axis=1) - along.min(axis=1)) / 2.0


@lru_cache(maxsize=32)
def _profile_grid(
    shape: tuple[int, int], border: int, step: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """Along coordinates of every profile of the four edges, concatenated in EDGES order, and the
    owner (edge index) of each."""
    h, w = shape
    horizontal = np.arange(border, w - border, step, dtype=np.intp)
    vertical = np.arange(border, h - border, step, dtype=np.intp)
    along = np.concatenate([horizontal, horizontal, vertical, vertical])
    owner = np.repeat(_ROWS, [horizontal.size, horizontal.size, vertical.size, vertical.size])
    along.setflags(write=False)
    owner.setflags(write=False)
    return along, owner


@lru_cache(maxsize=16)
def _moment_weights(n: int) -> FloatArray:
    """(2, n): ones and the positions 0.5 ... n - 0.5: the sum and first moment of n differences."""
    weights = np.vstack([np.ones(n), np.arange(n) + 0.5])
    weights.setflags(write=False)
    return weights


@lru_cache(maxsize=16)
def _ramp(n: int) -> FloatArray:
    """(n, 1) from 0 to 1: linear interpolation weights across a window of n samples."""
    ramp = np.linspace(0.0, 1.0, n)[:, None]
    ramp.setflags(write=False)
    return ramp


def _suppress_impulses(samples: FloatArray, threshold: float) -> None:
    """Replace isolated impulses (salt-and-pepper, hot pixels) in profiles across an edge, in place
    (``samples``: (sample, profile)).

    A clean blurred edge profile is monotonic, and the median of three neighbours leaves a monotonic
    sequence unchanged: only samples that differ from their 3-sample median by more than ``threshold``
    (DN) are replaced by it, so clean profiles are untouched and the estimator stays unbiased.
    """
    a, b, c = samples[:-2], samples[1:-1], samples[2:]
    med = np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))
    bad = np.abs(b - med) > threshold
    if bad.any():
        b[bad] = med[bad]


def _profile_points(
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32],
    *,
    along: npt.NDArray[np.intp],
    owner: npt.NDArray[np.intp],
    mu: FloatArray,
    half: int,
    impulse_dn: float,
    illumination: Illumination | None = None,
    with_spread: bool = True,
) -> _Profiles:
    """Sub-pixel edge positions of the profiles of all four edges in one gather (module docstring,
    step 2).

    Profile i runs across edge ``owner[i]`` at ``along[i]`` (a column for horizontal edges, a row for
    vertical ones), in a window of ``2 * half + 2`` samples about the predicted position ``mu[i]``.
    Profiles whose window does not fit inside the image are dropped. The numpy reference of the
    compiled kernel (``_ckernels.profiles``, run by ``_fine_compiled``).
    """
    h, w = img.shape
    n = 2 * half + 2
    vertical = _VERTICAL[owner]
    base = np.floor(mu).astype(np.intp) - half
    inside = (base >= 0) & (base + n - 1 < np.where(vertical, w, h))
    if not inside.all():
        along, owner, mu, base, vertical = (
            along[inside],
            owner[inside],
            mu[inside],
            base[inside],
            vertical[inside],
        )
    # one gather for every window: a vertical edge's window runs along a row (stride 1), a horizontal
    # edge's down a column (stride w). Layout (sample, profile): every step below works on whole
    # contiguous rows and reduces over the first axis (numpy reduces short last axes 10-20x slower).
    start = np.where(vertical, along * w + base, base * w + along)
    stride = np.where(vertical, 1, w)
    flat = start[None, :] + np.arange(n)[:, None] * stride[None, :]
    samples = np.take(img, flat).astype(np.float64)
    if illumination is not None:
        # flat field: the illumination is smooth, linear over one window: divide the samples by it,
        # evaluated at the window's two ends (whole pixels)
        end = base + (n - 1)
        xs = np.concatenate([np.where(vertical, base, along), np.where(vertical, end, along)])
        ys = np.concatenate([np.where(vertical, along, base), np.where(vertical, along, end)])
        v = illumination.at_pixels(xs, ys).reshape(2, -1)
        samples /= v[0][None, :] + (v[1] - v[0])[None, :] * _ramp(n)
    _suppress_impulses(samples, impulse_dn)
    d = samples[1:] - samples[:-1]
    # The window of differences is exactly symmetric about mu: 2 half + 1 differences at positions
    # 0.5 ... 2 half + 0.5 from the first sample, the two end ones weighted by the fractions of their
    # pixels inside (1 - f and f, f = mu - floor(mu)), the others fully. The polarity cancels in the
    # centroid and the spread; only the strength takes its sign.
    frac = mu - np.floor(mu)
    d[0] *= 1.0 - frac
    d[-1] *= frac
    pos = np.arange(n - 1) + 0.5
    moments = _moment_weights(n - 1) @ d  # (sum, sum of positions): one pass over the differences
    raw = moments[0]
    strength = raw * _POLARITY[owner]
    safe = np.where(strength > 0, raw, 1.0)
    rel = moments[1] / safe
    spread = ((d * (pos[:, None] - rel[None, :]) ** 2).sum(axis=0) / safe) if with_spread else None
    return _Profiles(owner, along.astype(np.float64), base + rel, strength, spread)


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


def precise_edges(gray: Gray8, params: MeasureParams) -> dict[Edge, EdgeFit]:
    """Four robust sub-pixel edge lines (module docstring); raises EdgeNotFoundError or GeometryError."""
    h, w = gray.shape
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32] = gray
    if params.camera_matrix is not None:
        img = undistort(gray.astype(np.float32), params)
        gray = np.clip(np.rint(img), 0, 255).astype(np.uint8)  # the coarse stage works on 8 bits
    coarse = coarse_cross(gray, params)
    models = _initial_models(coarse, (h, w))
    ck = compiled()
    if ck is not None:
        return _fine_compiled(ck, img, models, coarse.illumination, params)
    # the first pass steers from the coarse cross (a pixel or two off at the frame's ends): wide window
    half = params.window_px if params.window_px is not None else 8
    fits: dict[Edge, EdgeFit] = {}
    for pass_no in range(params.passes):
        last = pass_no == params.passes - 1
        # passes before the last only steer the windows: every 8th profile is plenty; the last
        # takes every profile_step-th column (row)
        along, owner = _profile_grid((h, w), half + 2, params.profile_step if last else 8)
        centre_along, half_groove = _crossing_extent(models)
        # the rounded land corners: no profile within the perpendicular groove plus a margin
        keep = np.abs(along - centre_along[owner]) > (half_groove + params.corner_margin_px)[owner]
        along, owner = along[keep], owner[keep]
        profiles = _profile_points(
            img,
            along=along,
            owner=owner,
            mu=models.slope[owner] * along + models.intercept[owner],
            half=half,
            impulse_dn=params.impulse_dn,
            illumination=coarse.illumination,  # vignetting would bias the profiles' centroids
            with_spread=not last,
        )
        fits, new_models, spread, problems = _fit_edges(profiles, models, params, half=half, last=last)
        if problems:
            found = tuple(e for e in EDGES if e not in problems)
            raise EdgeNotFoundError(describe_missing(problems), found=found)
        models = new_models
        if params.window_px is None and spread is not None:
            # window half-width: window_sigmas line-spread sigmas + 1 px (spread includes the two unit
            # boxes of the first difference: 2/12 px^2)
            sigma = math.sqrt(max(spread - 1.0 / 6.0, 0.1))
            half = int(np.clip(math.ceil(params.window_sigmas * sigma) + 1, 3, 12))
    return fits


def _fine_compiled(
    ck: ModuleType,
    img: npt.NDArray[np.uint8] | npt.NDArray[np.float32],
    models: _Models,
    illumination: Illumination | None,
    params: MeasureParams,
) -> dict[Edge, EdgeFit]:
    """``precise_edges``'s passes (the loop above, with ``_profile_points`` and ``_fit_edges``) in one
    call of the compiled kernel ``_ckernels.fine``; the same results within 1e-12 px."""
    h, w = img.shape
    slope = np.array(models.slope, np.float64)
    intercept = np.array(models.intercept, np.float64)
    colcoef, yn = illumination.pixel_tables() if illumination is not None else (None, None)
    stats = np.empty((9, len(EDGES)))
    points = np.empty((2 * (w + h), 2))
    stages, _, n_points = ck.fine(
        np.ascontiguousarray(img),
        slope,
        intercept,
        colcoef,
        yn,
        params.passes,
        -1 if params.window_px is None else params.window_px,
        params.window_sigmas,
        params.profile_step,
        params.corner_margin_px,
        params.impulse_dn,
        params.min_edge_points,
        params.min_contrast_dn,
        params.min_contrast_fraction,
        params.outlier_sigma,
        params.residual_limit_px,
        stats,
        points,
    )
    counts, contrast, n_good, n_in, rms, la, lb, lc = (row.tolist() for row in stats[:8])
    if any(stages):
        problems = {
            EDGES[i]: _failure(
                stage, params, count=int(counts[i]), contrast=contrast[i], good=int(n_good[i]), rms=rms[i]
            )
            for i, stage in enumerate(stages)
            if stage
        }
        found = tuple(e for e in EDGES if e not in problems)
        raise EdgeNotFoundError(describe_missing(problems), found=found)
    used = [int(n) for n in n_in]
    split = np.split(points[:n_points], np.cumsum(used[:-1]))
    return {
        edge: EdgeFit(
            name=edge,
            line=(la[i], lb[i], lc[i]),
            segmented=int(counts[i]),
            used=used[i],
            removed=int(counts[i]) - used[i],
            rms_px=rms[i],
            points=np.ascontiguousarray(split[i]),
        )
        for i, edge in enumerate(EDGES)
    }
