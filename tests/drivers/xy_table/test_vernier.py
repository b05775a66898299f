"""Micrometer arithmetic: inches of 0.0002 in divisions on the dial, mm at the interface."""

from __future__ import annotations

import pytest

from drivers.xy_table import DIVISION_IN, format_in, in_to_mm, is_on_grid, mm_to_in, snap_in


def test_one_division_is_five_micrometres() -> None:
    assert in_to_mm(DIVISION_IN) == pytest.approx(0.00508)
    assert mm_to_in(25.4) == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("inches", "snapped"),
    [(0.01, 0.01), (0.00013, 0.0002), (0.00009, 0.0), (-0.00031, -0.0004), (0.99999, 1.0)],
)
def test_snap_goes_to_the_nearest_whole_division(inches: float, snapped: float) -> None:
    assert snap_in(inches) == pytest.approx(snapped, abs=1e-12)
    assert is_on_grid(snap_in(inches))


@pytest.mark.parametrize(
    ("inches", "on_grid"), [(0.0102, True), (0.0, True), (0.01013, False), (0.0001, False)]
)
def test_is_on_grid_tolerates_float_rounding_only(inches: float, on_grid: bool) -> None:
    assert is_on_grid(inches) is on_grid


@pytest.mark.parametrize(
    ("inches", "text"),
    [
        (0.01, "0.0100 in"),
        (0.0, "0.0000 in"),
        (-0.0, "0.0000 in"),
        (mm_to_in(0.254), "0.0100 in"),
        (0.00013, "0.000130 in"),
    ],
)
def test_readings_are_written_as_the_operator_reads_them(inches: float, text: str) -> None:
    assert format_in(inches) == text
