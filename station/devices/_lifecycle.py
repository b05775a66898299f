"""Every device's lifecycle (``Connectable``) and identity (``DeviceIdentity``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable


@runtime_checkable
class Connectable(Protocol):
    """Every device's lifecycle: a factory builds it unconnected; ``connect`` opens it, ``close`` releases it.

    ``connect`` on a connected device does nothing; ``close`` is safe to call twice. The session runner
    connects all devices and closes them in reverse order in one place.
    """

    def connect(self) -> None:
        """Open the link (port, stream, prompt channel) and read the device's state."""

    def close(self) -> None:
        """Release the device; safe to call twice."""


@dataclass(frozen=True)
class DeviceIdentity:
    """Who a device is, recorded with every session: each field ``None`` where the device cannot say.

    ``model`` (e.g. the arm type from armstat, the camera's model name), ``serial`` (serial number or
    device id), ``port`` (serial port, video node, camera address), ``firmware`` (version text).
    """

    model: str | None = None
    serial: str | None = None
    port: str | None = None
    firmware: str | None = None


__all__ = [
    "Connectable",
    "DeviceIdentity",
]
