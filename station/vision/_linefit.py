"""Stage 6: the seed's recursive least-squares line fit with outlier removal (section 3.2.4, last part).

The seed fits ``y = a x + b`` (``x = a y + b`` for the transposed vertical edges), computes each point's
perpendicular distance to the line, forms the set without the farthest point, and compares the Pearson
correlation coefficients r of both sets: "if either the coefficient or the difference are below a
pre-determined tolerance then the smaller data set is used", until "both requirements are met" or 50
points are removed. The sentence is ambiguous and gives no tolerances (the seed paper: see README).

**Reading implemented here.** Keep removing the farthest point while

* ``|r| < corr_tol`` (the fit is not yet "linear enough"), or
* ``|r_without| - |r| > change_tol`` (removing the point still improves the correlation by more
  than the change tolerance),

and stop when neither holds or ``max_removals`` points are gone. Defaults: ``corr_tol = 0`` (off) because
Pearson's r measures slope, not fit quality: for an edge along the pixel rows r is near zero however good
the fit, so any positive tolerance removes ``max_removals`` points from every axis-aligned edge;
``change_tol = 1e-4``, small enough that a point several pixels off a sloped edge is removed. Both are
parameters and ``station sweep`` explores them.

The sums are updated incrementally (O(1) per removal) instead of refitting from scratch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


@dataclass(frozen=True)
class RecursiveFit:
    """``across = slope * along + intercept`` fitted to the kept points.

    ``kept``: mask (N,) of the points used; ``removed``: how many were dropped;
    ``rms_px``: rms perpendicular distance of the kept points (px); ``r``: final Pearson coefficient.
    """

    slope: float
    intercept: float
    kept: npt.NDArray[np.bool_]
    removed: int
    rms_px: float
    r: float


class _Sums:
    """Running sums of centred coordinates: slope, intercept and r in O(1)."""

    def __init__(self, t: npt.NDArray[np.float64], s: npt.NDArray[np.float64]) -> None:
        self.n = float(t.size)
        self.st = float(t.sum())
        self.ss = float(s.sum())
        self.stt = float(t @ t)
        self.sts = float(t @ s)
        self.sss = float(s @ s)

    def remove(self, t: float, s: float) -> None:
        self.n -= 1
        self.st -= t
        self.ss -= s
        self.stt -= t * t
        self.sts -= t * s
        self.sss -= s * s

    def line(self) -> tuple[float, float]:
        den = self.n * self.stt - self.st * self.st
        if den <= 0:
            raise ValueError("points are all in one column: no line can be fitted")
        slope = (self.n * self.sts - self.st * self.ss) / den
        return slope, (self.ss - slope * self.st) / self.n

    def r(self) -> float:
        return _pearson(self.n, self.st, self.ss, self.stt, self.sts, self.sss)

    def r_without(self, t: float, s: float) -> float:
        return _pearson(
            self.n - 1, self.st - t, self.ss - s, self.stt - t * t, self.sts - t * s, self.sss - s * s
        )


def _pearson(n: float, st: float, ss: float, stt: float, sts: float, sss: float) -> float:
    vt = n * stt - st * st
    vs = n * sss - ss * ss
    if vt <= 0 or vs <= 0:
        return 0.0
    return (n * sts - st * ss) / math.sqrt(vt * vs)


def recursive_fit(
    along: npt.NDArray[np.float64],
    across: npt.NDArray[np.float64],
    *,
    corr_tol: float,
    change_tol: float,
    max_removals: int,
    min_points: int = 3,
) -> RecursiveFit:
    """Fit ``across = slope * along + intercept``, removing outliers as the seed does (module docstring).

    Parameters
    ----------
    along, across : (N,) float arrays
        Coordinates along the edge (the seed's x for horizontal edges) and across it (y).
    corr_tol, change_tol, max_removals
        The two tolerances and the removal cap of the reading above.
    min_points
        Never remove points below this count.
    """
    if along.shape != across.shape or along.ndim != 1:
        raise ValueError("along and across must be 1-D arrays of the same length")
    if along.size < max(3, min_points):
        raise ValueError(f"{along.size} points are too few for a line fit")
    t0, s0 = float(along.mean()), float(across.mean())
    t = along - t0
    s = across - s0
    sums = _Sums(t, s)
    kept = np.ones(t.size, dtype=bool)
    removed = 0
    while removed < max_removals and sums.n > min_points:
        slope, intercept = sums.line()
        dist = np.abs(s - (slope * t + intercept))
        dist[~kept] = -1.0
        k = int(np.argmax(dist))
        r_all = abs(sums.r())
        r_less = abs(sums.r_without(float(t[k]), float(s[k])))
        if not (r_all < corr_tol or r_less - r_all > change_tol):
            break
        sums.remove(float(t[k]), float(s[k]))
        kept[k] = False
        removed += 1
    slope, intercept = sums.line()
    resid = (s[kept] - (slope * t[kept] + intercept)) / math.sqrt(1.0 + slope * slope)
    rms = float(np.sqrt(np.mean(resid * resid)))
    # undo the centring: across - s0 = slope (along - t0) + intercept
    return RecursiveFit(slope, intercept + s0 - slope * t0, kept, removed, rms, sums.r())
