"""``FakeDistanceSensor``: the Z distance sensor over the scene's height."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from station.devices import (
    DeviceConnectionError,
    DistanceSensorStatus,
    OutOfRangeError,
    SensorAlarmError,
)
from station.testing._recorder import _FakeDevice

FloatArray = npt.NDArray[np.float64]


class FakeDistanceSensor(_FakeDevice):
    """A distance sensor that reads ``distance()`` (mm; ``None``: no target) at once.

    Outside ``measuring_range_mm`` or ``None``: ``OutOfRangeError``; ``alarm = True``:
    ``SensorAlarmError``; any other failure through ``fail_on("read_mm", exc)``.
    """

    MODEL = "fake distance sensor"

    def __init__(
        self,
        distance: Callable[[], float | None] | float | None = 68.0,
        *,
        measuring_range_mm: tuple[float, float] = (55.0, 105.0),
    ) -> None:
        super().__init__()
        self._distance = distance if callable(distance) else (lambda: distance)
        self._range = measuring_range_mm
        self.alarm = False

    @property
    def measuring_range_mm(self) -> tuple[float, float]:
        return self._range

    def read_mm(self) -> float:
        self._call("read_mm")
        if not self.connected:
            raise DeviceConnectionError("fake distance sensor: connect() first")
        if self.alarm:
            raise SensorAlarmError("fake distance sensor: alarm", reply="alarm")
        d = self._distance()
        near, far = self._range
        if d is None or not near <= d <= far:
            raise OutOfRangeError(
                f"fake distance sensor: no target within its measuring range {near}-{far} mm", reply=str(d)
            )
        return float(d)

    def status(self) -> DistanceSensorStatus:
        try:
            d = self.read_mm()
        except OutOfRangeError as exc:
            return DistanceSensorStatus("out_of_range", str(exc))
        except SensorAlarmError as exc:
            return DistanceSensorStatus("alarm", str(exc))
        return DistanceSensorStatus("ok", f"{d:.3f} mm")


__all__ = [
    "FakeDistanceSensor",
]
