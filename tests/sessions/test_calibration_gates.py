"""The calibration's gates on its results object: the improvement over the nominal model is a fail
gate, the floor and the intervals' coverage warn; without held-out pairs they say what to do."""

from __future__ import annotations

from typing import Any

from station.kinds.calibration.gates import calibration_checks


def results(before: float | None, after: float | None, floor: float | None, **more: Any) -> dict[str, Any]:
    doc = {
        "residuals": {"after": {"rms_xy_mm": 0.010}},
        "cross_validation": {"after": {"rms_xy_mm": more.pop("held_rms_mm", 0.012)}},
    }
    return {
        "relative_error_um": {"before": before, "after": after, "floor": floor},
        "calibration": doc,
        "planned_configurations": 51,
        "configurations": more.pop("configurations", 51),
    }


def by_name(res: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {c["name"]: c for c in calibration_checks(res)}


def test_a_calibration_that_improves_on_the_nominal_model_passes() -> None:
    checks = by_name(results(975.0, 13.9, 10.3))
    assert all(c["passed"] for c in checks.values()), checks
    assert checks["relative_error_after_before"]["value"] == 13.9 / 975.0
    assert checks["relative_error_after_before"]["severity"] == "fail"


def test_a_calibration_worse_than_the_nominal_model_fails_its_gate() -> None:
    check = by_name(results(40.0, 55.0, 12.0))["relative_error_after_before"]
    assert check["passed"] is False
    assert check["severity"] == "fail"
    assert "does not improve the arm" in check["message"]


def test_far_above_the_floor_wide_held_out_residuals_and_skipped_configurations_warn() -> None:
    checks = by_name(results(975.0, 35.0, 14.0, held_rms_mm=0.031, configurations=40))
    for name in ("relative_error_after_floor", "interval_coverage", "configurations_measured"):
        assert checks[name]["passed"] is False
        assert checks[name]["severity"] == "warn"
    assert checks["relative_error_after_before"]["passed"] is True


def test_without_held_out_pairs_the_checks_say_what_to_do() -> None:
    res = results(None, None, 12.0)
    res["calibration"]["cross_validation"] = {}
    checks = by_name(res)
    gain = checks["relative_error_after_before"]
    assert (gain["passed"], gain["severity"]) == (False, "warn")
    assert "holdout_fraction" in gain["message"]
    assert "holdout_fraction" in checks["interval_coverage"]["message"]
