"""The focal length's scale from known heights: views square to the target, moved along the optical axis.

A view square to the target measures the image scale ``s = f / Z`` to about 1e-5, but not ``f`` and ``Z``
apart. The calibration's fit gives each view a distance ``Z_fit = f_fit / s``, so a wrong focal length
scales every fitted distance by ``f_fit / f``. Moving the camera along its axis between views of one
orientation changes the distance by what the distance sensor reads (its beam parallel to the axis, the
surface square to it: the sensor's mount offset cancels in the differences). The slope ``kappa`` of the
fitted distances against the readings, one line per orientation, is ``f_fit / f``.

Why it is needed: tilted views, which give the focal length in Zhang's method, lose their own depth of
field across the tilt; a blur that grows across a corner moves it (by the blur times its gradient, even in
a perfect image), and the fit reads that as perspective: measured on the twin at a physical f/4 macro's
defocus, +0.28 % on the focal length while OpenCV's uncertainty said 0.03 % (``TARGET.md``). Square views
have a uniform blur and no such bias.

Their blur does bias the fitted distance evenly about focus: a corner refined under a symmetric blur stays
put, but the lens's vignetting tilts the grey levels across it and the corners move by the blur squared
times that gradient, toward the image's centre (measured on noise-free twin frames at f/4: +1.4 um of
distance at 0.6 mm from focus, 2-3 um at 1-1.5 mm, either side). An even bias leaves the slope of
symmetric heights alone but not the scatter about the lines, so the fit takes a common term in the square
of the height from the middle of each orientation's readings when the heights allow it (three or more,
and views enough to spare the degree of freedom).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from station.camcal._errors import TooFewViewsError

__all__ = ["HeightScale", "SensorReading", "height_scale"]


@dataclass(frozen=True)
class SensorReading:
    """The distance sensor's reading for one view: ``group`` (views of one orientation, which differ only
    by a move along the optical axis) and ``distance_mm`` (the reading, averaged over a few samples)."""

    group: int
    distance_mm: float

    def __post_init__(self) -> None:
        if not math.isfinite(self.distance_mm):
            raise ValueError(f"a sensor reading must be finite, got {self.distance_mm!r}")


@dataclass(frozen=True)
class HeightScale:
    """The outcome of :func:`height_scale`.

    ``kappa``: fitted distances per mm of sensor reading (``f_fit / f``); ``u_rel``: its relative standard
    uncertainty, from the scatter about the lines (or the readings' stated uncertainty, whichever is
    larger) and the target's and the sensor's scale uncertainties; ``views`` / ``groups``: how many entered;
    ``residual_um``: the scatter of the fitted distances about the lines; ``range_mm``: the span of the
    readings within a group, the largest; ``curvature_um_per_mm2``: the even term in the height fitted
    with them (None when the heights are too few for it).
    """

    kappa: float
    u_rel: float
    views: int
    groups: int
    residual_um: float
    range_mm: float
    curvature_um_per_mm2: float | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "kappa": self.kappa,
            "u_rel": self.u_rel,
            "views": self.views,
            "groups": self.groups,
            "residual_um": self.residual_um,
            "range_mm": self.range_mm,
            "curvature_um_per_mm2": self.curvature_um_per_mm2,
        }


LEVEL_GAP_MM = 0.05
"""Readings closer than this are taken at one height (the arm's jitter and the sensor's noise: microns)."""


MIN_DOF_CURVED = 4
"""Degrees of freedom the fit must keep for the even term to be fitted (a few views: their scatter
alone is a poor estimate already)."""


def _levels(readings: Sequence[float]) -> int:
    """How many heights ``readings`` were taken at (gaps beyond :data:`LEVEL_GAP_MM` separate them)."""
    return 1 + int(np.count_nonzero(np.diff(np.sort(np.asarray(readings))) > LEVEL_GAP_MM))


def height_scale(
    distances_mm: Sequence[float],
    tilts_deg: Sequence[float],
    readings: Sequence[SensorReading | None],
    *,
    max_tilt_deg: float = 1.0,
    reading_u_mm: float = 0.001,
    pitch_u_rel: float = 0.0,
    sensor_scale_u_rel: float = 0.0,
) -> HeightScale:
    """Fit the fitted distances of near-square views against their sensor readings.

    Parameters
    ----------
    distances_mm : sequence of float
        Each view's distance from the camera's centre to the target's plane along the optical axis, as
        the calibration fitted it.
    tilts_deg : sequence of float
        Each view's tilt (the target's normal against the optical axis), as fitted.
    readings : sequence of SensorReading or None
        Each view's reading, or None for a view without one.
    max_tilt_deg : float
        Views tilted more are left out (the reading's change departs from the axis' by the tilt times the
        beam's unknown angle to the axis).
    reading_u_mm : float
        Standard uncertainty of one reading (the sensor's repeatability over the samples averaged), mm.
    pitch_u_rel, sensor_scale_u_rel : float
        Relative standard uncertainties of the target's pitch (its certificate) and of the sensor's scale
        (its linearity over the heights used), both carried into ``u_rel`` as they are.

    Raises
    ------
    TooFewViewsError
        No group with two near-square views at different readings.
    """
    if not len(distances_mm) == len(tilts_deg) == len(readings):
        raise ValueError("distances_mm, tilts_deg and readings need one entry per view")
    rows = [
        (r.group, r.distance_mm, d)
        for d, t, r in zip(distances_mm, tilts_deg, readings, strict=True)
        if r is not None and abs(t) <= max_tilt_deg
    ]
    by_group: dict[int, list[tuple[float, float]]] = {}
    for g, reading, d in rows:
        by_group.setdefault(g, []).append((reading, d))
    usable = {g: v for g, v in by_group.items() if len(v) >= 2 and np.ptp([r for r, _ in v]) > 0}
    if not usable:
        raise TooFewViewsError(
            f"no orientation has two views square to the target (within {max_tilt_deg} deg) at different "
            "sensor readings: take the square views at several heights, reading the distance sensor at each"
        )
    groups = sorted(usable)
    n = sum(len(usable[g]) for g in groups)
    A = np.zeros((n, 1 + len(groups)))
    y = np.zeros(n)
    i = 0
    for j, g in enumerate(groups):
        for reading, d in usable[g]:
            A[i, 0], A[i, 1 + j], y[i] = reading, 1.0, d
            i += 1
    # the term costs a degree of freedom: only with views enough to spare one (MIN_DOF_CURVED left)
    curved = (
        all(_levels([r for r, _ in usable[g]]) >= 3 for g in groups) and n - A.shape[1] - 1 >= MIN_DOF_CURVED
    )
    if curved:
        mid = {g: float(np.mean([r for r, _ in usable[g]])) for g in groups}
        A = np.column_stack([A, [(r - mid[g]) ** 2 for g in groups for r, _ in usable[g]]])
    sol, *_ = np.linalg.lstsq(A, y, rcond=None)
    kappa = float(sol[0])
    resid = y - A @ sol
    dof = n - A.shape[1]
    spread = float(np.sqrt(resid @ resid / dof)) if dof > 0 else 0.0
    # The slope's variance from the scatter about the lines, or from the readings' own uncertainty
    # (carried through the slope: d = kappa r), whichever is larger; few views make the scatter unreliable.
    sxx = float(np.linalg.inv(A.T @ A)[0, 0])
    sigma = max(spread, kappa * reading_u_mm) * math.sqrt(sxx)
    u_rel = math.sqrt((sigma / kappa) ** 2 + pitch_u_rel**2 + sensor_scale_u_rel**2)
    span = max(float(np.ptp([r for r, _ in usable[g]])) for g in groups)
    curvature = float(sol[-1]) * 1000.0 if curved else None
    return HeightScale(kappa, u_rel, n, len(groups), spread * 1000.0, span, curvature)
