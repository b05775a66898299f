"""Driver for a Keyence IL series laser displacement sensor read through a DL-RS1A RS-232C unit.

Build one by name through the station's registry (not connected: call ``connect()``)::

    sensor = station.config.build("distance_sensor", "keyence_il", port="/dev/ttyUSB0")
    sensor = station.config.build("distance_sensor", "keyence_il", port=twin.port,
                                  head={"model": "IL-065"}, link={"baudrate": 38400})
    sensor.connect(); sensor.read_mm()

The dialect (one module, ``_dialect``) and what is known of it: ``drivers/keyence_il/DIALECT.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import serial

from drivers.keyence_il._dialect import ERROR_NUMBERS, ErrorReplyError, Readout
from drivers.keyence_il._link import LineLink, LinkSettings
from drivers.keyence_il._sensor import HeadSettings, KeyenceIL
from station.devices import DistanceSensor


def open_distance_sensor(
    port: str | serial.SerialBase,
    *,
    head: HeadSettings | Mapping[str, Any] | None = None,
    link: LinkSettings | Mapping[str, Any] | None = None,
    baudrate: int | None = None,
) -> DistanceSensor:
    """The station's factory (``distance_sensor.keyence_il``): an unconnected sensor.

    ``head`` takes :class:`HeadSettings` fields (model, reference distance, range, direction, amplifier
    index), ``link`` :class:`LinkSettings` fields; ``baudrate`` overrides ``link``'s. Raises pydantic's
    ValidationError (a ValueError) on a bad value; nothing is opened.
    """
    link_values = link.model_dump() if isinstance(link, LinkSettings) else dict(link or {})
    if baudrate is not None:
        link_values["baudrate"] = baudrate
    head_settings = head if isinstance(head, HeadSettings) else HeadSettings.model_validate(dict(head or {}))
    return KeyenceIL(port, head=head_settings, link=LinkSettings.model_validate(link_values))


__all__ = [
    "ERROR_NUMBERS",
    "ErrorReplyError",
    "HeadSettings",
    "KeyenceIL",
    "LineLink",
    "LinkSettings",
    "Readout",
    "open_distance_sensor",
]
