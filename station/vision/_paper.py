"""Paper mode: the seed's algorithm, step by step (section 3.2), faithfully.

1 filter (3.2.1) -> 2 four directional Prewitt operators (3.2.2, eq. 4) -> 3 threshold at a fraction of
the maximum (3.2.3) -> 4 TestBox segmentation (3.2.4, eqs. 5-6) -> 5 3x3 raw-intensity moment (eqs. 7-8)
-> 6 recursive line fit -> 7 vertices -> 8 projective transform onto the groove-width square (3.2.5,
eqs. 9-12) -> 9 centre relative to the image origin, mm (3.2.6).
"""

from __future__ import annotations

from types import ModuleType

import cv2
import numpy as np
import numpy.typing as npt

from station.vision._edges import Edge, operator_responses, threshold_level
from station.vision._errors import EdgeNotFoundError, describe_missing
from station.vision._filters import apply_filter
from station.vision._geometry import VERTICAL, Line, normal_form
from station.vision._image import Gray8
from station.vision._kernels import compiled
from station.vision._linefit import recursive_fit
from station.vision._moment import intensity_moment
from station.vision._params import MeasureParams
from station.vision._result import EdgeFit
from station.vision._testbox import segment_edge_sparse

Float32Image = npt.NDArray[np.float32]
IntArray = npt.NDArray[np.intp]


#: The edge each response's polarity belongs to (``directional_responses``).
_NEGATIVE_EDGE: dict[bool, Edge] = {True: "top", False: "left"}
_POSITIVE_EDGE: dict[bool, Edge] = {True: "bottom", False: "right"}


def paper_edges(gray: Gray8, params: MeasureParams) -> dict[Edge, EdgeFit]:
    """Stages 1-6 for all four edges; raises EdgeNotFoundError naming what was not found."""
    # no filter: the operators work on the 8-bit image itself (the same values as on its float copy)
    filtered = (
        gray if params.filter == "none" else apply_filter(gray, params.filter, gauss_sigma=params.gauss_sigma)
    )
    fits: dict[Edge, EdgeFit] = {}
    problems: dict[Edge, str] = {}
    for horizontal, (response, lo, hi) in zip((True, False), _responses(filtered), strict=True):
        polarities = ((_NEGATIVE_EDGE[horizontal], -1.0, -lo), (_POSITIVE_EDGE[horizontal], 1.0, hi))
        # the threshold of each polarity (apply_threshold; none when its response is nowhere positive)
        levels = [
            max(threshold_level(peak, params.threshold), 0.0) if peak > 0 else None
            for _, _, peak in polarities
        ]
        candidates = _above(response, [lv for lv in levels if lv is not None])
        values = response.ravel()[candidates]
        for (edge, sign, _), level in zip(polarities, levels, strict=True):
            pixels = np.zeros((0, 2), np.intp)
            if level is not None:
                own = candidates[values > level] if sign > 0 else candidates[values < -level]
                pixels = segment_edge_sparse(
                    response,
                    sign,
                    edge,
                    level,
                    own,
                    testheight=params.testheight,
                    testwidth=params.testwidth,
                    skip=params.skip,
                    backoff=params.backoff_rows,
                )
            outcome = _edge_fit(gray, pixels, edge, params)
            if isinstance(outcome, str):
                problems[edge] = outcome
            else:
                fits[edge] = outcome
    if problems:
        raise EdgeNotFoundError(describe_missing(problems), found=tuple(fits))
    return fits


def _responses(
    filtered: Float32Image | npt.NDArray[np.uint8],
) -> tuple[tuple[Float32Image, float, float], tuple[Float32Image, float, float]]:
    """The operators' responses (gy, gx: ``operator_responses``), each with its minimum and maximum;
    on an 8-bit image by the compiled kernel when selected (``_kernels``: the same whole numbers and
    extremes, in one pass)."""
    ck = compiled()
    if ck is not None and filtered.dtype == np.uint8:
        gy = np.empty(filtered.shape, np.float32)
        gx = np.empty(filtered.shape, np.float32)
        ylo, yhi, xlo, xhi = ck.prewitt(np.ascontiguousarray(filtered), gy, gx)
        return (gy, ylo, yhi), (gx, xlo, xhi)
    gy, gx = operator_responses(filtered)
    (ylo, yhi, _, _), (xlo, xhi, _, _) = cv2.minMaxLoc(gy), cv2.minMaxLoc(gx)
    return (gy, ylo, yhi), (gx, xlo, xhi)


def _above(response: Float32Image, levels: list[float]) -> IntArray:
    """Flat indices of the pixels whose |response| exceeds the lower of ``levels``: every pixel above
    either polarity's threshold, in one pass (each edge then keeps its own). The levels are float32
    values (``threshold_level``), non-negative: by the compiled kernel when selected (``_kernels``),
    else numpy."""
    if not levels:
        return np.zeros(0, np.intp)
    ck = compiled()
    if ck is not None:
        found = np.frombuffer(ck.above(np.ascontiguousarray(response, np.float32), min(levels)), np.int64)
        return found.astype(np.intp, copy=False)
    return np.flatnonzero(np.abs(response) > min(levels))


def _edge_fit(gray: Gray8, pixels: IntArray, edge: Edge, params: MeasureParams) -> EdgeFit | str:
    """Stages 5-6 for one edge's segmented pixels: its fit, or why it was not found. By the compiled
    kernel when selected (``_kernels``), else numpy (the reference)."""
    ck = compiled()
    if ck is not None:
        return _edge_fit_compiled(ck, gray, pixels, edge, params)
    refined, valid = intensity_moment(gray, pixels)
    pts = refined[valid]
    if len(pts) < params.min_edge_points:
        return f"{len(pts)} points (at least {params.min_edge_points} needed)"
    vertical = edge in VERTICAL
    along, across = (pts[:, 1], pts[:, 0]) if vertical else (pts[:, 0], pts[:, 1])
    fit = recursive_fit(
        along,
        across,
        corr_tol=params.corr_tol,
        change_tol=params.change_tol,
        max_removals=params.max_removals,
        min_points=params.min_edge_points,
    )
    if fit.rms_px > params.residual_limit_px:
        return (
            f"its {int(fit.kept.sum())} points are not on a line (rms {fit.rms_px:.1f} px > "
            f"{params.residual_limit_px} px)"
        )
    line: Line = normal_form(fit.slope, fit.intercept, vertical=vertical)
    return EdgeFit(
        name=edge,
        line=line,
        segmented=len(pixels),
        used=int(fit.kept.sum()),
        removed=fit.removed,
        rms_px=fit.rms_px,
        points=np.ascontiguousarray(pts[fit.kept]),
    )


def _edge_fit_compiled(
    ck: ModuleType, gray: Gray8, pixels: IntArray, edge: Edge, params: MeasureParams
) -> EdgeFit | str:
    """``_edge_fit`` by ``_ckernels.edge_fit``: the same moments and the same sequence of removals."""
    vertical = edge in VERTICAL
    pts = np.empty((len(pixels), 2))
    kept = np.empty(len(pixels), np.bool_)
    valid, status, slope, intercept, removed, rms = ck.edge_fit(
        np.ascontiguousarray(gray),
        np.ascontiguousarray(pixels, np.int64),
        vertical,
        params.corr_tol,
        params.change_tol,
        params.max_removals,
        params.min_edge_points,
        pts,
        kept,
    )
    if status == 1:
        return f"{valid} points (at least {params.min_edge_points} needed)"
    if status == 2:
        raise ValueError("points are all in one column: no line can be fitted")  # as recursive_fit
    used = valid - int(removed)
    if rms > params.residual_limit_px:
        return f"its {used} points are not on a line (rms {rms:.1f} px > {params.residual_limit_px} px)"
    return EdgeFit(
        name=edge,
        line=normal_form(slope, intercept, vertical=vertical),
        segmented=len(pixels),
        used=used,
        removed=int(removed),
        rms_px=rms,
        points=np.ascontiguousarray(pts[:valid][kept[:valid]]),
    )
