"""The manual X-Y table's micrometers in the simulated world: what a reading really moves the carriage to."""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TableImperfections:
    """How the manual micrometer table differs from its readings (mm, deg)."""

    skew_deg: float = 0.05
    resolution_in: float = 0.0002
    backlash_mm: float = 0.001

    def __post_init__(self) -> None:
        if self.resolution_in < 0 or self.backlash_mm < 0 or not math.isfinite(self.skew_deg):
            raise ValueError("table resolution and backlash must be >= 0 and skew finite")


class TableAxis:
    """One micrometer axis: the reading the operator sets, the carriage position it really gives.

    The carriage follows the reading rounded to the micrometer's resolution, lagging by half the backlash
    behind the last direction of travel.
    """

    def __init__(self, resolution_mm: float, backlash_mm: float) -> None:
        self._resolution = resolution_mm
        self._backlash = backlash_mm
        self.reading_mm = 0.0
        self.position_mm = 0.0
        self._direction = 0.0

    def set_reading(self, reading_mm: float) -> None:
        if not math.isfinite(reading_mm):
            raise ValueError(f"table reading must be finite, got {reading_mm!r}")
        step = reading_mm - self.reading_mm
        if step != 0.0:
            self._direction = math.copysign(1.0, step)
        self.reading_mm = reading_mm
        settled = round(reading_mm / self._resolution) * self._resolution if self._resolution else reading_mm
        self.position_mm = settled - self._direction * self._backlash / 2.0


__all__ = ["TableAxis", "TableImperfections"]
