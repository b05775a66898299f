"""The IL series laser displacement sensor behind a DL-RS1A, as a station ``DistanceSensor``."""

from __future__ import annotations

import logging
import math
import threading
from typing import Literal

import serial
from pydantic import BaseModel, ConfigDict, Field, model_validator

from drivers.keyence_il import _dialect as dialect
from drivers.keyence_il._link import LineLink, LinkSettings
from station.devices import (
    DeviceIdentity,
    DeviceProtocolError,
    DistanceSensorStatus,
    OutOfRangeError,
    SensorAlarmError,
)

log = logging.getLogger(__name__)


class HeadSettings(BaseModel):
    """The sensor head and how the amplifier's reading becomes a distance.

    Defaults: the IL-065 head [M catalogue]: reference distance 65 mm, measuring range 55 to 105 mm.
    The amplifier prints a displacement from the reference distance; that it grows as the target moves
    away (``increases="away"``) is an assumption [A] (the amplifier's direction setting can invert it):
    check it once by moving a target away from the head.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    model: str = Field("IL-065", min_length=1)
    reference_distance_mm: float = Field(65.0, gt=0)
    measuring_range_mm: tuple[float, float] = (55.0, 105.0)
    increases: Literal["away", "toward"] = "away"
    amplifier_index: int = Field(0, ge=0, le=14, description="position on the DL-RS1A: 0 = main unit")

    @model_validator(mode="after")
    def _range(self) -> HeadSettings:
        near, far = self.measuring_range_mm
        if not (0 < near < far and math.isfinite(far)):
            raise ValueError(f"measuring_range_mm must be (near, far) with 0 < near < far, got {(near, far)}")
        return self


class KeyenceIL:
    """A Keyence IL head and amplifier read through a DL-RS1A RS-232C unit (``M0``).

    One thread at a time talks to the unit (a lock serialises queries).
    """

    def __init__(
        self,
        port: str | serial.SerialBase,
        *,
        head: HeadSettings | None = None,
        link: LinkSettings | None = None,
    ) -> None:
        self.head = head or HeadSettings()
        self.link = LineLink(port, link)
        self._lock = threading.Lock()

    # ---------------------------------------------------------------- lifecycle

    @property
    def measuring_range_mm(self) -> tuple[float, float]:
        return self.head.measuring_range_mm

    def connect(self) -> None:
        """Open the port and check that the unit answers ``M0`` (a reading out of range is fine here)."""
        if self.link.is_open:
            return
        self.link.open()
        try:
            self._readout()
        except BaseException:
            self.link.close()
            raise

    def close(self) -> None:
        self.link.close()

    def identity(self) -> DeviceIdentity:
        """As configured: the DL-RS1A has no command that reports the head's model or serial."""
        return DeviceIdentity(model=f"Keyence {self.head.model} via DL-RS1A", port=str(self.link.name))

    # ---------------------------------------------------------------- reading

    def _readout(self) -> dialect.Readout:
        with self._lock:
            line = self.link.query(dialect.encode(dialect.MEASURE), what=dialect.MEASURE)
        fields = dialect.parse_reply(dialect.MEASURE, line)
        i = self.head.amplifier_index
        if i >= len(fields):
            raise DeviceProtocolError(
                f"the reply {line!r} has {len(fields)} amplifier(s); amplifier_index {i} is not among them:"
                " check the configuration"
            )
        return dialect.parse_readout(fields[i])

    def _distance(self, readout: dialect.Readout) -> float:
        near, far = self.head.measuring_range_mm
        if readout.kind == "error":
            raise SensorAlarmError(
                f"the {self.head.model} amplifier reports an error ({readout.text}): check the head's cable"
                " and the amplifier's display, then reset it",
                reply=readout.text,
            )
        if readout.kind != "value":
            why = {
                "above": "beyond the display range",
                "below": "beyond the display range",
                "invalid": "no valid measurement: no target in range or too little light",
            }[readout.kind]
            raise OutOfRangeError(
                f"the {self.head.model} reads {readout.text} ({why}); bring a surface within"
                f" {near:g}-{far:g} mm of the head, facing it",
                reply=readout.text,
            )
        assert readout.value_mm is not None
        sign = 1.0 if self.head.increases == "away" else -1.0
        distance = self.head.reference_distance_mm + sign * readout.value_mm
        if not near <= distance <= far:
            raise OutOfRangeError(
                f"the {self.head.model} reads {readout.text}: {distance:.3f} mm, outside its measuring range"
                f" {near:g}-{far:g} mm; move it so that the surface is within the range",
                reply=readout.text,
            )
        return distance

    def read_mm(self) -> float:
        """One distance, mm from the head's reference point (see :class:`HeadSettings`)."""
        return self._distance(self._readout())

    def status(self) -> DistanceSensorStatus:
        """From one ``M0`` reading: ok (a distance), out_of_range or alarm. Link errors raise."""
        readout = self._readout()
        try:
            d = self._distance(readout)
        except OutOfRangeError as exc:
            return DistanceSensorStatus("out_of_range", str(exc))
        except SensorAlarmError as exc:
            return DistanceSensorStatus("alarm", str(exc))
        return DistanceSensorStatus("ok", f"{d:.3f} mm ({readout.text})")


__all__ = ["HeadSettings", "KeyenceIL"]
