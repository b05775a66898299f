"""Vernier micrometer arithmetic: mm at the interface, inches of 0.0002 in divisions on the dial."""

from __future__ import annotations

import math

MM_PER_INCH = 25.4
DIVISION_IN = 0.0002
"""One division of the table's micrometers, in inches."""

_GRID_TOLERANCE_DIVISIONS = 1e-6


def mm_to_in(mm: float) -> float:
    """Millimetres to inches."""
    return mm / MM_PER_INCH


def in_to_mm(inches: float) -> float:
    """Inches to millimetres."""
    return inches * MM_PER_INCH


def divisions(inches: float) -> float:
    """How many 0.0002 in divisions ``inches`` is (not rounded)."""
    return inches / DIVISION_IN


def snap_in(inches: float) -> float:
    """The nearest reading the operator can set: a whole number of divisions, in inches."""
    return round(divisions(inches)) * DIVISION_IN


def is_on_grid(inches: float) -> bool:
    """Whether ``inches`` is a whole number of divisions (to rounding error)."""
    d = divisions(inches)
    return math.isfinite(d) and abs(d - round(d)) <= _GRID_TOLERANCE_DIVISIONS * max(1.0, abs(d))


def format_in(inches: float) -> str:
    """A reading as the operator writes it: four decimals on the grid (``0.0100 in``), six off it."""
    text = f"{snap_in(inches) + 0.0:.4f}" if is_on_grid(inches) else f"{inches:.6f}"
    return f"{text} in"
