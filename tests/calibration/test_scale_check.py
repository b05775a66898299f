"""The gate-ready check: the magnification a calibration found against the groove widths it measured."""

from __future__ import annotations

import numpy as np
import pytest

from station.calibration import CalibrationError, magnification_check
from station.vision import NOMINAL_GROOVE_WIDTH_MM

from .conftest import FittedRulers


def _widths(true_width_mm: float, px_per_mm: float, n: int = 60, seed: int = 0) -> list[float]:
    """Both grooves' widths of ``n / 2`` captures at the capture plane, as measured (0.02 px noise)."""
    rng = np.random.default_rng(seed)
    return list(true_width_mm * px_per_mm + rng.normal(0.0, 0.02, n))


def test_the_identified_magnification_agrees_with_the_grooves_and_the_nominal_one_does_not(
    fitted_rulers: FittedRulers,
) -> None:
    mag = fitted_rulers.result.magnification
    assert mag is not None
    assert mag.sigma is not None
    true_scale = fitted_rulers.truth.px_per_mm  # 1.3 % above the nominal
    widths = _widths(0.790, true_scale)  # an artifact 0.004 mm narrower than drawn: within its tolerance
    ok = magnification_check(mag.px_per_mm, widths, px_per_mm_sigma=mag.sigma)
    assert ok.passed
    assert ok.disagreement == 0.0
    assert ok.implied_width_mm == pytest.approx(0.790, abs=2e-4)
    assert ok.to_json()["passed"] is True
    # a station trusting the nominal scale makes the grooves 1.3 % wider: beyond the drawing's +0
    wrong = magnification_check(mag.nominal_px_per_mm, widths)
    assert not wrong.passed
    assert wrong.disagreement == pytest.approx(0.790 * 1.013 / NOMINAL_GROOVE_WIDTH_MM - 1.0, abs=5e-4)
    gate = wrong.to_json()
    assert gate["name"] == "magnification_groove_width"
    assert gate["severity"] == "fail"
    assert gate["passed"] is False
    assert gate["limit"] == pytest.approx([NOMINAL_GROOVE_WIDTH_MM - 0.0508, NOMINAL_GROOVE_WIDTH_MM])
    assert "wider than the artifact can be" in gate["message"]
    assert "check the rulers' description" in gate["message"]


def test_a_scale_too_large_shows_the_grooves_narrower_than_the_tolerance_allows() -> None:
    widths = _widths(NOMINAL_GROOVE_WIDTH_MM - 0.04, 100.0)  # an artifact near its narrowest
    assert magnification_check(100.0, widths).passed
    too_large = magnification_check(103.0, widths)  # 3 %: 0.754 / 1.03 = 0.732 mm, below 0.743
    assert not too_large.passed
    assert too_large.disagreement < 0
    assert "narrower" in too_large.message


def test_the_uncertainties_decide_at_the_boundary() -> None:
    widths = _widths(NOMINAL_GROOVE_WIDTH_MM, 100.0)
    edge = 100.0 / (1.0 + 0.0005)  # the grooves 0.05 % wider than the drawing's largest
    assert not magnification_check(edge, widths).passed
    assert magnification_check(edge, widths, px_per_mm_sigma=0.05).passed  # 0.05 % sigma: within 3


def test_refuses_what_it_cannot_check() -> None:
    with pytest.raises(CalibrationError, match="needs the groove widths"):
        magnification_check(100.0, [])
    with pytest.raises(CalibrationError, match="must be positive"):
        magnification_check(-1.0, [79.0])
    with pytest.raises(CalibrationError, match="finite"):
        magnification_check(100.0, [float("nan")])
