"""Precise mode's step 3 (``_precise``'s docstring): the robust orthogonal line fit of the four edges
from their sub-pixel profile points, all edges at once, and why an edge was not found.

The numpy reference of the compiled kernel's fit (``_ckernels.fine``); the profile points themselves
(step 2) and the passes around the fit live in ``_precise``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.vision._edges import EDGES, Edge
from station.vision._geometry import VERTICAL
from station.vision._params import MeasureParams
from station.vision._result import EdgeFit

FloatArray = npt.NDArray[np.float64]


#: Edge order of every per-edge array below: EDGES (top, bottom, left, right); left and right are vertical.
_VERTICAL = np.array([e in VERTICAL for e in EDGES])
#: +1 where the intensity rises across the edge in the scan direction (+y or +x), -1 where it falls.
_POLARITY = np.array([-1.0, 1.0, -1.0, 1.0])
_ROWS = np.arange(len(EDGES))


@dataclass(frozen=True)
class _Models:
    """The four edges as ``across = slope * along + intercept`` in image px (along = x for horizontal
    edges, y for vertical ones), arrays in EDGES order."""

    slope: FloatArray
    intercept: FloatArray

    def lines(self) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Normal forms ``a x + b y = c`` (``_geometry.normal_form``), as arrays (a, b, c)."""
        norm = np.hypot(1.0, self.slope)
        a = np.where(_VERTICAL, 1.0, -self.slope) / norm
        b = np.where(_VERTICAL, -self.slope, 1.0) / norm
        return a, b, self.intercept / norm


@dataclass(frozen=True)
class _Profiles:
    """Sub-pixel edge positions of the profiles whose window fits inside the image.

    ``owner``: edge index (EDGES order, grouped); ``along``: the profile's column (horizontal edges)
    or row (vertical edges); ``across``: the edge position along the profile (px); ``strength``: the
    window's summed first difference (the local contrast, DN); ``spread``: the second central moment
    of the differences (px^2), or None.
    """

    owner: npt.NDArray[np.intp]
    along: FloatArray
    across: FloatArray
    strength: FloatArray
    spread: FloatArray | None


class _Groups:
    """Per-edge statistics of values grouped by edge (``owner`` sorted), each in a few array calls.

    A selection (boolean mask over all values) becomes the weight matrix ``onehot * sel`` (edges x
    values): per-edge counts and sums are then one matrix product, and medians sort a padded
    (edges x longest group) grid.
    """

    def __init__(self, owner: npt.NDArray[np.intp]) -> None:
        self.owner = owner
        counts = np.bincount(owner, minlength=len(EDGES))
        self.counts = counts
        self.width = max(int(counts.max()), 1)
        slot = np.arange(owner.size) - (np.cumsum(counts) - counts)[owner]
        self.flatpos = owner * self.width + slot
        self.onehot = (owner[None, :] == _ROWS[:, None]).astype(np.float64)

    def weights(self, sel: npt.NDArray[np.bool_]) -> FloatArray:
        """(edges, values): 1 where a value is selected and belongs to the edge."""
        return self.onehot * sel[None, :]

    def count(self, sel: npt.NDArray[np.bool_]) -> npt.NDArray[np.intp]:
        return (self.onehot @ sel.astype(np.float64)).astype(np.intp)

    def median(
        self, values: FloatArray, sel: npt.NDArray[np.bool_], n_sel: npt.NDArray[np.intp]
    ) -> FloatArray:
        """Per edge, the upper median of ``values[sel]`` (``fast_median``'s; ``n_sel``: the selected
        count per edge); inf for an empty group."""
        flat = np.full(len(EDGES) * self.width, np.inf)
        flat[self.flatpos] = np.where(sel, values, np.inf)
        grid = flat.reshape(len(EDGES), self.width)
        grid.sort(axis=1)
        return grid[_ROWS, n_sel // 2]


def _tls(
    groups: _Groups, x: FloatArray, y: FloatArray, sel: npt.NDArray[np.bool_]
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per edge, the total-least-squares line through its selected points (the principal axis):
    arrays (a, b, c) of ``a x + b y = c``."""
    wts = groups.weights(sel)
    n = np.maximum(wts.sum(axis=1), 1.0)
    mx, my = (wts @ x) / n, (wts @ y) / n
    dx, dy = x - mx[groups.owner], y - my[groups.owner]
    sxx, syy, sxy = wts @ (dx * dx), wts @ (dy * dy), wts @ (dx * dy)
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # direction of the line
    nx, ny = -np.sin(phi), np.cos(phi)
    return nx, ny, nx * mx + ny * my


def _failure(
    stage: int,
    params: MeasureParams,
    *,
    count: int = 0,
    contrast: float = 0.0,
    good: int = 0,
    rms: float = 0.0,
) -> str:
    """Why an edge was not found, by the first test it failed (``_ckernels.fine``'s stage numbers; the
    numpy reference ``_fit_edges`` uses the same)."""
    if stage == 1:
        return (
            f"only {count} of its profiles fit inside the frame (at least {params.min_edge_points}): "
            "it runs too close to the border; keep the groove corners 10 px or more inside the frame"
        )
    if stage == 2:
        return f"its contrast is {contrast:.1f} DN (at least {params.min_contrast_dn} DN)"
    if stage == 3:
        return f"only {good} profiles show the edge"
    if stage == 4:
        return "its points do not lie on a line"
    return f"its points are not on a line (rms {rms:.2f} px)"


def _fit_edges(
    p: _Profiles, models: _Models, params: MeasureParams, *, half: int, last: bool
) -> tuple[dict[Edge, EdgeFit], _Models, float | None, dict[Edge, str]]:
    """The four edges' lines from their profiles (module docstring, step 3), all edges at once.

    Returns (fits on the last pass, new models, median line spread, problems: per edge the reason it
    was not found). The numpy reference of the compiled kernel (``_fine_compiled``).
    """
    groups = _Groups(p.owner)
    owner, t, a = p.owner, p.along, p.across
    problems: dict[Edge, str] = {}
    ok = np.ones(len(EDGES), bool)

    def fail(where: npt.NDArray[np.bool_], reason: Callable[[int], str]) -> None:
        if not (where & ok).any():
            return
        for i in np.flatnonzero(where & ok).tolist():
            problems[EDGES[i]] = reason(i)
        ok[where] = False

    counts = groups.counts
    fail(counts < params.min_edge_points, lambda i: _failure(1, params, count=int(counts[i])))
    contrast = groups.median(p.strength, np.ones(owner.size, bool), counts)
    fail(contrast < params.min_contrast_dn, lambda i: _failure(2, params, contrast=float(contrast[i])))
    tol = half / 2.0 if last else half - 2.0
    good = ok[owner] & (p.strength > params.min_contrast_fraction * contrast[owner])
    good &= np.abs(a - (models.slope[owner] * t + models.intercept[owner])) < tol
    n_good = groups.count(good)
    fail(n_good < params.min_edge_points, lambda i: _failure(3, params, good=int(n_good[i])))
    vertical = _VERTICAL[owner]
    x, y = np.where(vertical, a, t), np.where(vertical, t, a)
    # robust orthogonal fit: residuals first from the previous pass's line, outliers beyond
    # outlier_sigma robust (1.4826 MAD) sigmas dropped, the rest fitted by total least squares
    la, lb, lc = models.lines()
    inliers = good & ok[owner]
    resid = la[owner] * x + lb[owner] * y - lc[owner]
    n_in = groups.count(inliers)
    for _ in range(2 if last else 1):
        med = groups.median(resid, inliers, n_in)
        dev = np.abs(resid - med[owner])
        sigma = np.maximum(1.4826 * groups.median(dev, inliers, n_in), 1e-3)
        inliers = good & ok[owner] & (dev <= params.outlier_sigma * sigma[owner])
        n_in = groups.count(inliers)
        fail(n_in < 3, lambda i: _failure(4, params))
        inliers &= ok[owner]
        la, lb, lc = _tls(groups, x, y, inliers)
        resid = la[owner] * x + lb[owner] * y - lc[owner]
    flip = np.where(_VERTICAL, la < 0, lb < 0)
    sign = np.where(flip, -1.0, 1.0)
    la, lb, lc = la * sign, lb * sign, lc * sign
    n_in = np.maximum(n_in, 1)
    rms = np.sqrt(groups.weights(inliers) @ (resid * resid) / n_in)
    if last:  # earlier passes only steer the windows
        limit = params.residual_limit_px
        fail(rms > limit, lambda i: _failure(5, params, rms=float(rms[i])))
    fits: dict[Edge, EdgeFit] = {}
    if last and not problems:
        # the inliers keep the profiles' order, grouped by edge: one selection, split by the counts
        points = np.split(np.column_stack([x[inliers], y[inliers]]), np.cumsum(n_in)[:-1])
        for i, edge in enumerate(EDGES):
            used = int(n_in[i])
            fits[edge] = EdgeFit(
                name=edge,
                line=(float(la[i]), float(lb[i]), float(lc[i])),
                segmented=int(counts[i]),
                used=used,
                removed=int(counts[i]) - used,
                rms_px=float(rms[i]),
                points=points[i],
            )
    spread = None
    if p.spread is not None and ok.all():
        spread = float(np.sort(groups.median(p.spread, good, n_good))[len(EDGES) // 2])
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(_VERTICAL, -lb / la, -la / lb)
        intercept = np.where(_VERTICAL, lc / la, lc / lb)
    return fits, _Models(slope, intercept), spread, problems
