"""The Z distance sensor's interface: ``DistanceSensor``, its status and errors."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from station.devices._errors import (
    DeviceError,
)
from station.devices._lifecycle import DeviceIdentity


class OutOfRangeError(DeviceError):
    """The distance sensor has no valid distance: the target is outside its measuring range, the beam
    misses it, or too little light comes back (steep incidence, dark or shiny surface).

    Nothing is wrong with the link: move the sensor so that a surface lies within ``measuring_range_mm``
    along its beam, then read again. ``reply`` is what the sensor sent.
    """

    def __init__(self, message: str, *, reply: str = "") -> None:
        super().__init__(message)
        self.reply = reply


class SensorAlarmError(DeviceError):
    """The distance sensor reports an alarm of its own (amplifier or head error, laser stopped).

    ``reply`` is what it sent; the message says what to check at the sensor.
    """

    def __init__(self, message: str, *, reply: str = "") -> None:
        super().__init__(message)
        self.reply = reply


DISTANCE_STATES = ("ok", "out_of_range", "alarm")
"""What :class:`DistanceSensorStatus` ``state`` can be."""


@dataclass(frozen=True)
class DistanceSensorStatus:
    """What the distance sensor reports now: ``state`` one of ``DISTANCE_STATES``; ``text`` says it in
    words (the sensor's own reply where it has one)."""

    state: str
    text: str = ""

    def __post_init__(self) -> None:
        if self.state not in DISTANCE_STATES:
            raise ValueError(f"state must be one of {DISTANCE_STATES}, got {self.state!r}")

    @property
    def ok(self) -> bool:
        return self.state == "ok"


@runtime_checkable
class DistanceSensor(Protocol):
    """A one-point distance sensor (a laser displacement sensor beside the camera), in mm.

    ``read_mm`` returns one distance from the sensor's reference point along its beam, or raises: never a
    made-up number. No valid distance raises :class:`OutOfRangeError`, an alarm of the sensor
    :class:`SensorAlarmError`, an unparseable or refused reply ``DeviceProtocolError``, no reply
    ``DeviceTimeoutError``, a lost link ``DeviceConnectionError`` (``connect()`` again).
    ``measuring_range_mm`` is ``(near, far)``: distances it can measure.
    """

    @property
    def measuring_range_mm(self) -> tuple[float, float]:
        """(near, far) limits of the measuring range, mm from the sensor's reference point."""

    def connect(self) -> None:
        """Open the link and check that the sensor answers."""

    def close(self) -> None:
        """Release the link; safe to call twice."""

    def read_mm(self) -> float:
        """One distance (mm) measured now."""

    def status(self) -> DistanceSensorStatus:
        """Whether a valid distance is available now (ok), or why not (out_of_range, alarm)."""

    def identity(self) -> DeviceIdentity:
        """Model, serial, port and firmware as far as the sensor (or its configuration) says."""


__all__ = [
    "DISTANCE_STATES",
    "DistanceSensor",
    "DistanceSensorStatus",
    "OutOfRangeError",
    "SensorAlarmError",
]
