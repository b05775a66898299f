"""Opening a serial port the way every station driver does: exclusively, with actionable errors.

Shared by the drivers that speak over pyserial (the CRS C500C console, the Keyence DL-RS1A): a port given
by name, pty path or pyserial URL is opened with ``serial_for_url(..., exclusive=True)``; an already built
``serial.SerialBase`` (a test's loop:// port) is configured and opened as it is. A port another program
holds is a :class:`~station.devices.DeviceBusyError` ("in use"); any other failure a
:class:`~station.devices.DeviceConnectionError` naming the port and what to check.
"""

from __future__ import annotations

from typing import Any

import serial

from station.devices import DeviceBusyError, DeviceConnectionError

try:  # pyserial's POSIX flush() raises termios.error, which is not an OSError
    from termios import error as _TermiosError  # noqa: N812 - an exception class
except ImportError:  # pragma: no cover - Windows
    _TermiosError = OSError  # type: ignore[misc,assignment]

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


__all__ = ["LINK_ERRORS", "open_port"]
