"""``FakeTable``: the X-Y table, moving at once (mm)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from station.devices import (
    DeviceConnectionError,
    MotionRejectedError,
    TablePosition,
)
from station.testing._recorder import _FakeDevice

FloatArray = npt.NDArray[np.float64]


class FakeTable(_FakeDevice):
    """An X-Y table that moves at once within its travel (mm); no operator."""

    MODEL = "fake X-Y table"

    def __init__(self, travel_mm: tuple[float, float] = (-12.7, 12.7)) -> None:
        super().__init__()
        self.travel_mm = travel_mm
        self.pos = TablePosition(0.0, 0.0)

    def check_target(self, x_mm: float, y_mm: float) -> None:
        lo, hi = self.travel_mm
        for axis, v in (("x", x_mm), ("y", y_mm)):
            if not math.isfinite(v) or not lo <= v <= hi:
                raise MotionRejectedError(f"table {axis} = {v} mm is outside its travel {lo} to {hi} mm")

    def position(self) -> TablePosition:
        return self.pos

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        self._call("move_to", x_mm, y_mm)
        if not self.connected:
            raise DeviceConnectionError("fake table is not connected: call connect() first")
        self.check_target(x_mm, y_mm)
        self.pos = TablePosition(float(x_mm), float(y_mm))
        return self.pos


__all__ = [
    "FakeTable",
]
