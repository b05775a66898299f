"""The calibration's gates (issue 19): the checks its report already states, in the gates' form.

* ``relative_error_after_before`` (fail): the calibrated model's relative error over held-out
  configurations below the nominal model's (ratio after / before < 1). A calibration that does not
  improve on the nominal model has identified noise or a wrong cell, and must not be used.
* ``relative_error_after_floor`` (warn): after within :data:`AFTER_FLOOR_LIMIT` x the floor (what the
  arm's repeatability and the measurement leave, estimated from each configuration's return capture).
  The floor estimate itself is uncertain (about -60 % / +50 % on the simulated cell), so this warns.
* ``interval_coverage`` (warn): the held-out residuals' RMS within :data:`COVERAGE_LIMIT` x the fitted
  residuals' RMS. The 95 % intervals come from the fit's covariance, which takes the fitted residuals
  as the noise: held-out residuals much larger mean the model misses something and the intervals
  cover the true values less often than stated.
* ``configurations_measured`` (warn): every planned configuration aligned and captured.
* With rulers (issue 22): ``absolute_error_after_before`` (fail): the calibrated model's error along
  the rulers (held-out frames far apart) below the nominal model's; ``magnification_groove_width``
  (fail): the magnification the rulers gave agrees with the groove widths the crossings measured, within
  the artifact's tolerance (``station.calibration.magnification_check``): otherwise the rulers'
  description, the artifact or the captures are wrong.

Without held-out pairs (``holdout_fraction = 0``) the relative error is not computed: the first two
checks then fail as warnings that say so.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from station.plans._gates import Check, at_least, at_most, checks_json

#: after / floor: the report's target.
AFTER_FLOOR_LIMIT = 2.0
#: held-out RMS / fitted RMS.
COVERAGE_LIMIT = 2.0


def _ratio(num: Any, den: Any) -> float | None:
    if num is None or den is None or float(den) <= 0:
        return None
    return float(num) / float(den)


def calibration_checks(results: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The checks of a calibration session's results (``analyse_calibration``'s object)."""
    rel = results.get("relative_error_um", {})
    before, after, floor = rel.get("before"), rel.get("after"), rel.get("floor")
    hold = "hold configurations out of the fit (holdout_fraction) to check it"
    gain = _ratio(after, before)
    checks: list[Check] = [
        at_most(
            "relative_error_after_before",
            gain,
            1.0,
            severity="fail" if gain is not None else "warn",
            ok="the calibrated model's relative error is {value} x the nominal model's",
            bad=(
                "the calibrated model's relative error is {value} x the nominal model's (limit {limit}): "
                "the calibration does not improve the arm; check the cell's artifacts and the captures, "
                "then run the calibration again"
            )
            if gain is not None
            else f"no held-out pairs: the improvement over the nominal model is not checked; {hold}",
        ),
        at_most(
            "relative_error_after_floor",
            _ratio(after, floor),
            AFTER_FLOOR_LIMIT,
            severity="warn",
            ok="the calibrated model's relative error is {value} x the floor",
            bad="the calibrated model's relative error is {value} x the floor (target {limit} x): the model "
            "leaves more than the arm's repeatability; more configurations or turns may help"
            if after is not None and floor is not None
            else f"the relative error or its floor was not computed, so their ratio is not checked; {hold}",
        ),
    ]
    doc = results.get("calibration", {})
    fitted = (doc.get("residuals") or {}).get("after") or {}
    held = (doc.get("cross_validation") or {}).get("after") or {}
    coverage = _ratio(held.get("rms_xy_mm"), fitted.get("rms_xy_mm"))
    checks.append(
        at_most(
            "interval_coverage",
            coverage,
            COVERAGE_LIMIT,
            severity="warn",
            ok="held-out residuals {value} x the fitted ones: the 95 % intervals are as stated",
            bad="held-out residuals {value} x the fitted ones (limit {limit} x): the intervals are too "
            "narrow for this data; read them as lower bounds"
            if coverage is not None
            else f"no held-out residuals: the intervals' coverage is not checked; {hold}",
        )
    )
    planned = results.get("planned_configurations")
    if planned:
        checks.append(
            at_least(
                "configurations_measured",
                results.get("configurations"),
                planned,
                severity="warn",
                ok="all {value} planned configurations measured",
                bad="{value} of {limit} planned configurations measured (the others were skipped: see the "
                "session's warnings)",
            )
        )
    absolute = results.get("absolute_error_um")
    if absolute is not None:
        ratio = _ratio(absolute.get("after"), absolute.get("before"))
        checks.append(
            at_most(
                "absolute_error_after_before",
                ratio,
                1.0,
                severity="fail" if ratio is not None else "warn",
                ok="the calibrated model's error along the rulers is {value} x the nominal model's",
                bad=(
                    "the calibrated model's error along the rulers is {value} x the nominal model's (limit "
                    "{limit}): check the rulers' description in [[calibration.rulers]], then run again"
                )
                if ratio is not None
                else "no held-out pairs of ruler frames far apart: the error along the rulers is not "
                f"checked; {hold}",
            )
        )
    out = checks_json(checks)
    magnification = results.get("magnification_check")
    if magnification is not None:
        out.append(dict(magnification))
    return out
