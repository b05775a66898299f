"""A serial port's lifecycle the way every station driver has it: opened exclusively, with actionable
errors, closed safely (``SerialPort``; ``open_port`` opens one).

Shared by the drivers that speak over pyserial (the CRS C500C console, the Keyence DL-RS1A): a port given
by name, pty path or pyserial URL is opened with ``serial_for_url(..., exclusive=True)``; an already built
``serial.SerialBase`` (a test's loop:// port) is configured and opened as it is. A port another program
holds is a :class:`~station.devices.DeviceBusyError` ("in use"); any other failure a
:class:`~station.devices.DeviceConnectionError` naming the port and what to check.
"""

from __future__ import annotations

import logging
from typing import Any

import serial

from station.devices import DeviceBusyError, DeviceConnectionError

log = logging.getLogger(__name__)

try:  # pyserial's POSIX flush() raises termios.error, which is not an OSError
    from termios import error as _TermiosError  # noqa: N812 - an exception class
except ImportError:  # pragma: no cover - Windows
    _TermiosError = OSError  # type: ignore[misc,assignment]

LINE_SETTINGS = ("baudrate", "bytesize", "parity", "stopbits", "xonxoff", "rtscts")
"""pyserial's line settings a driver's link settings may carry (``SerialPort.open_with``)."""

LINK_ERRORS: tuple[type[Exception], ...] = (serial.SerialException, OSError, _TermiosError)
"""What pyserial raises when a port is lost mid-use (unplugged, closed, a pty's other end gone)."""


def open_port(
    port: str | serial.SerialBase,
    name: str,
    *,
    timeout_s: float,
    write_timeout_s: float,
    **line: Any,
) -> serial.SerialBase:
    """Open ``port`` exclusively and return it. ``line``: pyserial's line settings (baudrate, bytesize,
    parity, stopbits, xonxoff, rtscts) for a port given by name; an injected port keeps its own."""
    try:
        if isinstance(port, serial.SerialBase):
            port.timeout = timeout_s
            port.write_timeout = write_timeout_s
            if not port.is_open:
                port.open()
            return port
        opened = serial.serial_for_url(
            port, do_not_open=True, timeout=timeout_s, write_timeout=write_timeout_s, exclusive=True, **line
        )
        opened.open()
        return opened
    except serial.SerialException as exc:
        if "exclusively lock" in str(exc):
            raise DeviceBusyError(
                f"{name!r} is in use by another program (it holds the port's exclusive lock):"
                " close that program, then connect again"
            ) from exc
        raise DeviceConnectionError(
            f"cannot open {name!r}: {exc}; check the port name, the cable and that no other program holds it"
        ) from exc
    except (OSError, _TermiosError, ValueError) as exc:
        raise DeviceConnectionError(
            f"cannot open {name!r}: {exc}; check the port name, the cable and that no other program holds it"
        ) from exc


class SerialPort:
    """One serial port's lifecycle, shared by the drivers' line transports.

    ``port`` is a name, pty path or pyserial URL (opened exclusively by :meth:`open`, released by
    :meth:`close`) or an already built ``serial.SerialBase`` (a test's port: configured and opened as it
    is, and kept after :meth:`close` so that it can be opened again). ``name`` is what errors show.
    """

    def __init__(self, port: str | serial.SerialBase) -> None:
        self._injected = isinstance(port, serial.SerialBase)
        self._port_arg = port
        self._serial: serial.SerialBase | None = port if isinstance(port, serial.SerialBase) else None
        self.name = port if isinstance(port, str) else str(getattr(port, "port", None) or type(port).__name__)

    @property
    def is_open(self) -> bool:
        return self._serial is not None and bool(self._serial.is_open)

    def open(self, *, timeout_s: float, write_timeout_s: float, **line: Any) -> None:
        """Open the port (see :func:`open_port`); a second call does nothing."""
        if self.is_open:
            return
        self._serial = open_port(
            self._port_arg, self.name, timeout_s=timeout_s, write_timeout_s=write_timeout_s, **line
        )

    def open_with(self, settings: Any) -> None:
        """Open with a driver's link settings: ``poll_s`` (the read timeout), ``reply_timeout_s`` (the
        write timeout) and those of ``LINE_SETTINGS`` it has."""
        line = {k: getattr(settings, k) for k in LINE_SETTINGS if hasattr(settings, k)}
        self.open(timeout_s=settings.poll_s, write_timeout_s=settings.reply_timeout_s, **line)

    def close(self) -> None:
        """Close the port; safe to call twice (a failure to close is only logged: the port is gone)."""
        if self._serial is None:
            return
        try:
            self._serial.close()
        except LINK_ERRORS as exc:
            log.debug("closing %s: %s", self.name, exc)
        if not self._injected:
            self._serial = None

    def require(self, not_open: str) -> serial.SerialBase:
        """The open port, or :class:`~station.devices.DeviceConnectionError` ``not_open`` (say what to do)."""
        if self._serial is None or not self._serial.is_open:
            raise DeviceConnectionError(not_open)
        return self._serial


__all__ = ["LINE_SETTINGS", "LINK_ERRORS", "SerialPort", "open_port"]
