"""The closed-form noise limit of the ruler's position (``station.vision._ruler_bound``)."""

from __future__ import annotations

import math

import pytest

from station.vision import RulerSpec
from station.vision._ruler_bound import (
    edge_information,
    graduation_position_bound_px,
    ruler_view_bound_px,
)

#: The nominal preset's figures, about: 165 DN of contrast, 0.9 DN of noise, 1 px of blur, 12
#: graduations in view, 220 px of lines.
NOMINAL = {
    "contrast_dn": 165.0,
    "noise_dn": 0.9,
    "blur_sigma_px": 1.0,
    "graduations": 12.0,
    "line_rows_px": 220.0,
}


def test_the_bound_follows_the_edges_count_contrast_noise_and_blur() -> None:
    base = {
        "contrast_dn": 165.0,
        "noise_dn": 0.9,
        "blur_sigma_px": 1.0,
        "graduations": 12.0,
        "line_rows_px": 220.0,
    }
    b = graduation_position_bound_px(**base)
    assert graduation_position_bound_px(**{**base, "graduations": 48.0}) == pytest.approx(b / 2, rel=1e-12)
    assert graduation_position_bound_px(**{**base, "noise_dn": 1.8}) == pytest.approx(2 * b, rel=1e-12)
    assert graduation_position_bound_px(**{**base, "contrast_dn": 82.5}) == pytest.approx(2 * b, rel=1e-12)
    blurred = graduation_position_bound_px(**{**base, "blur_sigma_px": 2.0})
    assert blurred == pytest.approx(b * (4 + 1 / 12) ** 0.25 / (1 + 1 / 12) ** 0.25, rel=1e-12)


def test_a_row_s_information_is_the_sampled_edge_s() -> None:
    # sum over a row of the squared slope of a blurred, pixel-averaged edge: the closed form's integral
    sigma, contrast, noise = 1.0, 100.0, 1.0
    x = [k + 0.37 for k in range(-30, 31)]

    def covered(c: float) -> float:  # pixel [c - 1/2, c + 1/2] average of the blurred step Phi(-x / sigma)
        def integral(a: float) -> float:
            z = a / sigma
            return a * 0.5 * math.erfc(z / math.sqrt(2)) - sigma * math.exp(-0.5 * z * z) / math.sqrt(
                2 * math.pi
            )

        return integral(c + 0.5) - integral(c - 0.5)

    h = 1e-5
    total = sum(((covered(c + h) - covered(c - h)) / (2 * h) * contrast / noise) ** 2 for c in x)
    assert total == pytest.approx(edge_information(contrast, noise, sigma), rel=0.02)


def test_a_view_of_the_design_s_ruler() -> None:
    spec = RulerSpec()
    b = ruler_view_bound_px(
        spec, px_per_mm=100.0, graduated_mm=6.4, contrast_dn=165.0, noise_dn=0.9, blur_sigma_px=1.0
    )
    rows = sum(hi - lo for lo, hi in spec.line_segments_mm) * 100.0
    assert b == pytest.approx(
        graduation_position_bound_px(
            contrast_dn=165.0, noise_dn=0.9, blur_sigma_px=1.0, graduations=12.8, line_rows_px=rows
        ),
        rel=1e-12,
    )
    assert 5e-5 < b < 5e-4  # a tenth of a thousandth of a pixel, as the numerical bound


@pytest.mark.parametrize("bad", [{"contrast_dn": 0.0}, {"noise_dn": -1.0}, {"graduations": 0.0}])
def test_nonsense_is_refused(bad: dict[str, float]) -> None:
    args = {
        "contrast_dn": 165.0,
        "noise_dn": 0.9,
        "blur_sigma_px": 1.0,
        "graduations": 12.0,
        "line_rows_px": 220.0,
    }
    with pytest.raises(ValueError, match="must be > 0"):
        graduation_position_bound_px(**{**args, **bad})
