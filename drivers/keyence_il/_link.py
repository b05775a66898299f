"""A line transport over pyserial for the DL-RS1A: one command, one CR LF-ended reply, with a deadline.

Knows nothing of commands. Turns pyserial and OS failures into the station's device errors: a port that
cannot be opened or goes away ``DeviceConnectionError`` (``DeviceBusyError`` when another program holds
it), no reply in time ``DeviceTimeoutError``.
"""

from __future__ import annotations

import logging
import time
from typing import Literal

import serial
from pydantic import BaseModel, ConfigDict, Field

from drivers._serial import LINK_ERRORS, SerialPort
from station.devices import DeviceConnectionError, DeviceTimeoutError

log = logging.getLogger(__name__)


class LinkSettings(BaseModel):
    """Serial parameters and timeouts. The DL-RS1A's baud rate, parity and stop bits are set with its
    setup switches [M]; 38400 8N1 is this driver's default [A]: set them to match the unit."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    baudrate: Literal[9600, 19200, 38400, 57600, 115200] = 38400
    bytesize: Literal[7, 8] = 8
    parity: Literal["N", "E", "O"] = "N"
    stopbits: Literal[1, 2] = 1
    reply_timeout_s: float = Field(
        1.0, gt=0, description="wait for a reply ([M]: the unit answers within 1 s)"
    )
    poll_s: float = Field(0.02, gt=0, description="read granularity; the port's read timeout")
    max_reply_bytes: int = Field(512, ge=16, description="a longer reply without CR LF is garbage")


class LineLink:
    """``query(bytes) -> str``: stale input discarded, the command written, one reply line read."""

    def __init__(self, port: str | serial.SerialBase, settings: LinkSettings | None = None) -> None:
        self.settings = settings or LinkSettings()
        self._link = SerialPort(port)
        self.name = self._link.name

    @property
    def is_open(self) -> bool:
        return self._link.is_open

    def open(self) -> None:
        """Open the port exclusively (a name, pty path or pyserial URL); a second call does nothing."""
        self._link.open_with(self.settings)

    def close(self) -> None:
        """Close the port; safe to call twice."""
        self._link.close()

    def _lost(self, exc: Exception) -> DeviceConnectionError:
        self.close()
        return DeviceConnectionError(
            f"lost the link to the distance sensor on {self.name!r} ({exc}); check the cable and the"
            " DL-RS1A's power, then connect() again"
        )

    def query(self, data: bytes, *, what: str) -> str:
        """Write ``data`` and return the next reply line (without CR LF), decoded as ASCII.

        Input left over from an earlier, late reply is discarded first, so that a reply always answers
        the command just sent. Bytes that are not ASCII come back as U+FFFD (the caller's parser then
        refuses the line).
        """
        port = self._link.require(f"the distance sensor on {self.name!r} is not open: connect() first")
        s = self.settings
        try:
            if port.in_waiting:
                stale = port.read(port.in_waiting)
                log.debug("<- discarded %r", stale)
            log.debug("-> %r", data)
            port.write(data)
            port.flush()
            raw = bytearray()
            deadline = time.monotonic() + s.reply_timeout_s
            while b"\r\n" not in raw:
                if time.monotonic() >= deadline:
                    got = bytes(raw).decode("ascii", errors="replace")
                    raise DeviceTimeoutError(
                        f"no reply from the distance sensor on {self.name!r} within {s.reply_timeout_s:g} s"
                        f" after {what!r}"
                        + (f" (received {got!r})" if got else " (received nothing)")
                        + f"; check the cable, the DL-RS1A's power and that it is set to {s.baudrate} baud"
                    )
                if len(raw) > s.max_reply_bytes:
                    break
                raw += port.read(max(1, port.in_waiting))
        except LINK_ERRORS as exc:
            raise self._lost(exc) from exc
        line, _, rest = bytes(raw).partition(b"\r\n")
        if rest:
            log.debug("<- after the reply %r", rest)
        text = line.decode("ascii", errors="replace")
        log.debug("<- %r", text)
        return text


__all__ = ["LINK_ERRORS", "LineLink", "LinkSettings"]
