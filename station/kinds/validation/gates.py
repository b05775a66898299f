"""The validation's gates (issue 19): what a validation's result must satisfy to be believed.

* ``table_moves`` (fail, also live): once the table has moved :data:`MOVE_MIN_UM` or more from its
  start, the measured displacement must be at least :data:`MOVE_MIN_RATIO` of the commanded one. A
  camera that looks at something that does not move with the table (the arm off its reference pose,
  over another artifact) measures about nothing; the session stops at once.
* ``groove_width`` (fail): the groove width the similarity fit estimates lies in the artifact's
  tolerance band (nominal 1/32 in, +0/-0.002 in by default; a plan parameter) widened by three of its
  standard uncertainties. A micrometer misread or a table that does not move drags the scale, and with
  it this estimate, far outside what the artifact can be.
* ``rigid_mean`` / ``rigid_max`` (fail): the rigid fit's errors within the mode's limits (2 / 6 um in
  precise mode, 20 / 50 um in paper mode by default: the seed's own 8.0 / 16.8 um pass in paper mode, a
  micrometer turn misread (635 um) never does).
* ``positions_measured`` (warn): every planned position measured.
* ``resume_position`` (fail, also live): after a resume, the last confirmed position captured again
  measures within :data:`RESUME_LIMIT_UM` of its measurement before the interruption.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

import numpy as np
import numpy.typing as npt

from station.plans._gates import Check, GateError, at_least, at_most, within

FloatArray = npt.NDArray[np.float64]

INCH_MM = 25.4
#: The artifact's groove width: nominal 1/32 in, +0/-0.002 in (mm).
GROOVE_BAND_MM = ((1 / 32 - 0.002) * INCH_MM, (1 / 32) * INCH_MM)
#: The band is widened by this many standard uncertainties of the estimate.
GROOVE_BAND_SIGMAS = 3.0
#: The rigid fit's (mean, max) error limits per measurement mode (um).
RIGID_LIMITS_UM = {"precise": (2.0, 6.0), "paper": (20.0, 50.0)}
#: The table-moves gate applies once the table has moved this far from its start (um) ...
MOVE_MIN_UM = 25.0
#: ... and then asks the image to show at least this fraction of the commanded displacement.
MOVE_MIN_RATIO = 0.5
#: A resumed validation continues only if the last confirmed position measures within this (um).
RESUME_LIMIT_UM = 2.0

NOT_SEEN = (
    "the camera does not see the table's artifact move: is the arm at its reference pose over the table?"
)
SETUP_MOVED = "the setup moved while the station was down; start a new validation"


class CaptureResult(Protocol):
    """What the gates read of a capture (``station.plans.CaptureResult``)."""

    @property
    def step_index(self) -> int: ...
    @property
    def meta(self) -> Mapping[str, Any]: ...
    @property
    def measurement(self) -> Mapping[str, Any] | None: ...


def measured(captures: Sequence[CaptureResult]) -> list[CaptureResult]:
    return [c for c in captures if c.measurement is not None and c.measurement.get("ok")]


def table_point_mm(measurement: Mapping[str, Any]) -> tuple[float, float]:
    """Where a measurement places the table's artifact (mm, its own axes), up to a constant: the
    crossing's ``center_mm``; on a ruler, minus the ruler point under the reference pixel
    (``position_mm``, ``offset_mm``: absolute), which moves against the table."""
    if measurement.get("artifact") == "ruler":
        return -float(measurement["position_mm"]), -float(measurement["offset_mm"])
    x, y = measurement["center_mm"]
    return float(x), float(y)


def _center_um(captures: Sequence[CaptureResult]) -> FloatArray | None:
    """The mean table point (:func:`table_point_mm`) of measured captures (um), None when none was."""
    pts = [table_point_mm(c.measurement) for c in measured(captures) if c.measurement is not None]
    if not pts:
        return None
    return np.mean(np.asarray(pts, dtype=np.float64), axis=0) * 1000.0


def move_ratio(commanded_um: FloatArray, measured_um: FloatArray) -> tuple[float | None, int | None]:
    """The smallest ratio |measured| / |commanded| of the displacements from the first position over the
    positions the table moved :data:`MOVE_MIN_UM` or more from it, and that position's row; (None,
    None) when no position moved that far."""
    c = np.asarray(commanded_um, dtype=np.float64) - commanded_um[0]
    m = np.asarray(measured_um, dtype=np.float64) - measured_um[0]
    far = np.linalg.norm(c, axis=1) >= MOVE_MIN_UM
    if not far.any():
        return None, None
    ratio = np.linalg.norm(m, axis=1)[far] / np.linalg.norm(c, axis=1)[far]
    worst = int(np.argmin(ratio))
    return float(ratio[worst]), int(np.flatnonzero(far)[worst])


def table_moves_check(
    commanded_um: FloatArray, measured_um: FloatArray, labels: Sequence[Any]
) -> Check | None:
    """The ``table_moves`` gate over positions in order (None when the table never moved far enough)."""
    ratio, row = move_ratio(commanded_um, measured_um)
    if ratio is None or row is None:
        return None
    c = float(np.linalg.norm(np.asarray(commanded_um[row]) - commanded_um[0]))
    m = float(np.linalg.norm(np.asarray(measured_um[row]) - measured_um[0]))
    where = f"position {labels[row]}: the table moved {c:.2f} um, the image {m:.2f} um"
    return at_least(
        "table_moves",
        ratio,
        MOVE_MIN_RATIO,
        severity="fail",
        ok="the image follows the table (smallest measured/commanded displacement {value})",
        bad=f"{NOT_SEEN} ({where})",
    )


def live_table_moves(captures: Sequence[CaptureResult]) -> None:
    """During the session: raise GateError as soon as the image does not follow the table."""
    by_position: dict[int, list[CaptureResult]] = {}
    for c in captures:
        if c.meta.get("role") == "position":
            by_position.setdefault(int(c.meta["position"]), []).append(c)
    keys, commanded, seen = [], [], []
    for k in sorted(by_position):
        centre = _center_um(by_position[k])
        if centre is None:
            continue
        keys.append(k)
        commanded.append(by_position[k][0].meta["commanded_um"])
        seen.append(centre)
    if len(keys) < 2:
        return
    check = table_moves_check(np.array(commanded, float), np.array(seen, float), keys)
    if check is not None and not check.passed:
        raise GateError(check.message)


def resume_check(captures: Sequence[CaptureResult]) -> Check | None:
    """The latest resume's re-capture of the last confirmed position against that position's
    measurement before the interruption (None when the session was never resumed)."""
    again = [c for c in captures if c.meta.get("role") == "resume_check"]
    if not again:
        return None
    latest = max(c.step_index for c in again)
    again = [c for c in again if c.step_index == latest]
    k = again[0].meta.get("position")
    before = [c for c in captures if c.meta.get("role") == "position" and c.meta.get("position") == k]
    now_um, then_um = _center_um(again), _center_um(before)
    moved = None if now_um is None or then_um is None else float(np.linalg.norm(now_um - then_um))
    if moved is None:
        why = "was not measured before the interruption" if then_um is None else "could not be measured again"
        bad = f"{SETUP_MOVED} (position {k} {why}, so the setup cannot be checked)"
    else:
        bad = (
            f"{SETUP_MOVED} (position {k} measures {{value}} um from before the interruption; "
            "limit {limit} um)"
        )
    return at_most(
        "resume_position",
        moved,
        RESUME_LIMIT_UM,
        severity="fail",
        ok=f"after the resume, position {k} measures {{value}} um from before the interruption",
        bad=bad,
    )


def live_resume(captures: Sequence[CaptureResult]) -> None:
    check = resume_check(captures)
    if check is not None and not check.passed:
        raise GateError(check.message)


def groove_check(width_mm: float, u_mm: float, band_mm: tuple[float, float]) -> Check:
    widen = GROOVE_BAND_SIGMAS * u_mm if math.isfinite(u_mm) else 0.0
    lo, hi = band_mm[0] - widen, band_mm[1] + widen
    return within(
        "groove_width",
        width_mm,
        (lo, hi),
        severity="fail",
        ok="the groove width estimate {value} mm lies in the artifact's band [{low}, {high}] mm",
        bad="the groove width estimate {value} mm is outside the artifact's band [{low}, {high}] mm "
        "(its tolerance widened by 3 u): the table's moves and the image disagree in scale; check the "
        "micrometer readings and that the artifact moves with the table, then start a new validation",
    )


def rigid_checks(mean_um: float, max_um: float, limits: tuple[float, float], mode: str) -> list[Check]:
    advice = "check the micrometer readings and the table's artifact, then start a new validation"
    return [
        at_most(
            "rigid_mean",
            mean_um,
            limits[0],
            severity="fail",
            ok=f"the rigid fit's mean error {{value}} um is within {{limit}} um ({mode} mode)",
            bad=f"the rigid fit's mean error {{value}} um exceeds {{limit}} um ({mode} mode): {advice}",
        ),
        at_most(
            "rigid_max",
            max_um,
            limits[1],
            severity="fail",
            ok=f"the rigid fit's largest error {{value}} um is within {{limit}} um ({mode} mode)",
            bad=f"the rigid fit's largest error {{value}} um exceeds {{limit}} um ({mode} mode): {advice}",
        ),
    ]


def positions_check(n: int, planned: int) -> Check:
    return at_least(
        "positions_measured",
        n,
        planned,
        severity="warn",
        ok="all {value} planned positions measured",
        bad="{value} of {limit} positions measured; the others' captures are kept in the record",
    )
