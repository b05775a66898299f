"""Paper mode: the seed's algorithm, step by step (section 3.2), faithfully.

1 filter (3.2.1) -> 2 four directional Prewitt operators (3.2.2, eq. 4) -> 3 threshold at a fraction of
the maximum (3.2.3) -> 4 TestBox segmentation (3.2.4, eqs. 5-6) -> 5 3x3 raw-intensity moment (eqs. 7-8)
-> 6 recursive line fit -> 7 vertices -> 8 projective transform onto the groove-width square (3.2.5,
eqs. 9-12) -> 9 centre relative to the image origin, mm (3.2.6).
"""

from __future__ import annotations

import numpy as np

from station.vision._edges import EDGES, Edge, apply_threshold, directional_responses
from station.vision._errors import EdgeNotFoundError, describe_missing
from station.vision._filters import apply_filter
from station.vision._geometry import VERTICAL, Line, normal_form
from station.vision._image import Gray8
from station.vision._linefit import recursive_fit
from station.vision._moment import intensity_moment
from station.vision._params import MeasureParams
from station.vision._result import EdgeFit
from station.vision._testbox import segment_edge


def paper_edges(gray: Gray8, params: MeasureParams) -> dict[Edge, EdgeFit]:
    """Stages 1-6 for all four edges; raises EdgeNotFoundError naming what was not found."""
    filtered = apply_filter(gray, params.filter, gauss_sigma=params.gauss_sigma)
    responses = directional_responses(filtered)
    fits: dict[Edge, EdgeFit] = {}
    problems: dict[Edge, str] = {}
    for edge in EDGES:
        thresholded = apply_threshold(responses[edge], params.threshold)
        pixels = segment_edge(
            thresholded,
            edge,
            testheight=params.testheight,
            testwidth=params.testwidth,
            skip=params.skip,
            backoff=params.backoff_rows,
        )
        refined, valid = intensity_moment(gray, pixels)
        pts = refined[valid]
        if len(pts) < params.min_edge_points:
            problems[edge] = f"{len(pts)} points (at least {params.min_edge_points} needed)"
            continue
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
            problems[edge] = (
                f"its {int(fit.kept.sum())} points are not on a line (rms {fit.rms_px:.1f} px > "
                f"{params.residual_limit_px} px)"
            )
            continue
        line: Line = normal_form(fit.slope, fit.intercept, vertical=vertical)
        fits[edge] = EdgeFit(
            name=edge,
            line=line,
            segmented=len(pixels),
            used=int(fit.kept.sum()),
            removed=fit.removed,
            rms_px=fit.rms_px,
            points=np.ascontiguousarray(pts[fit.kept]),
        )
    if problems:
        raise EdgeNotFoundError(describe_missing(problems), found=tuple(fits))
    return fits
