"""The ruler's description (``RulerSpec``): its defaults, its checks, and the code's properties that
the design (station/vision/RULER.md) relies on."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from station.vision import RulerCode, RulerSpec


def test_the_design_ruler() -> None:
    spec = RulerSpec()
    assert (spec.length_mm, spec.pitch_mm) == (250.0, 0.5)
    assert spec.graduation_count == 501
    assert spec.cell_mm == pytest.approx(0.125)
    assert spec.cell_count == 2001
    assert spec.code.period == 2047
    # the two parts of the lines differ in length (which way the ruler runs), code track between
    (lo0, lo1), (hi0, hi1) = spec.line_segments_mm
    assert lo0 == -1.6
    assert hi1 == 1.6
    assert lo1 - lo0 == pytest.approx(1.3)
    assert hi1 - hi0 == pytest.approx(0.9)
    assert spec.code_track_mm == pytest.approx((-0.1, 0.5))


def test_every_window_of_the_code_names_one_place() -> None:
    spec = RulerSpec()
    bits = spec.code_bits()
    assert set(np.unique(bits)) == {0, 1}
    index = spec.code_index()
    # every `order`-cell window of the 2001 cells occurs once: 2001 - 11 + 1 distinct places
    assert len(index) == spec.cell_count - spec.code.order + 1
    j = 1234
    value = int("".join(str(b) for b in bits[j : j + spec.code.order]), 2)
    assert index[value] == j


def test_the_shortest_stretch_in_the_envelope_reads_cells_three_apart() -> None:
    # RULER.md: 3.5 mm of the pattern wholly in view (the envelope's shortest) shows 28 cells; any
    # two places with the same cell phase then differ in at least 3 of them
    spec = RulerSpec()
    bits = spec.code_bits().astype(np.int8)
    windows = np.lib.stride_tricks.sliding_window_view(bits, 28)
    per = spec.code.cells_per_pitch
    nearest = min(
        int(
            (windows[phase::per][:, None, :] != windows[phase::per][None, :, :])
            .sum(-1)[~np.eye(len(windows[phase::per]), dtype=bool)]
            .min()
        )
        for phase in range(per)
    )
    assert nearest >= 3


def test_the_certificate_uncertainty_grows_with_the_position() -> None:
    spec = RulerSpec(pitch_u_ppm=0.2, graduation_u_nm=10.0)
    assert spec.position_u_nm(0.0) == pytest.approx(10.0)
    # 250 mm at 0.2 ppm is 50 nm, with the graduation's 10 nm in quadrature
    assert spec.position_u_nm(250.0) == pytest.approx(float(np.hypot(10.0, 50.0)))


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"length_mm": 250.3}, "whole number of pitches"),
        ({"line_width_mm": 0.45}, "20-80 % of the pitch"),
        ({"code": {"order": 11, "taps": (11, 5)}}, "not a primitive polynomial"),
        ({"code": {"order": 10, "taps": (10, 7)}}, "too short for 2001 cells"),
        ({"code_offset_mm": 0.0}, "unequal parts"),
        ({"pitch_mm": float("nan")}, "finite"),
        ({"colour": "red"}, "Extra inputs"),
    ],
)
def test_a_bad_description_is_refused_naming_the_fix(changes: dict[str, object], match: str) -> None:
    with pytest.raises(ValidationError, match=match):
        RulerSpec.model_validate(changes)


def test_code_taps_must_end_at_the_order() -> None:
    with pytest.raises(ValidationError, match="largest = order"):
        RulerCode(order=11, taps=(10, 7))
