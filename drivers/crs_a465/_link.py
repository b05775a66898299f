"""The serial link to a C500C: settings, and a thin line transport over pyserial.

The transport accepts a port name, a pyserial URL (``loop://``, ``socket://host:port``, a pty path)
or an already built ``serial.SerialBase`` (tests inject fakes that way). It writes and reads text
lines, logs every line sent and received at debug level, waits for the prompt with a deadline, and
turns pyserial and OS failures into the station's device errors. It knows nothing of commands.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Literal

import serial
from pydantic import BaseModel, ConfigDict, Field

from drivers._serial import LINK_ERRORS, SerialPort
from station.devices import DeviceConnectionError, DeviceTimeoutError

log = logging.getLogger(__name__)

# pyserial on a port closed by another thread while in use: its file descriptor is None mid-call
CLOSED_UNDER_US: tuple[type[Exception], ...] = (TypeError, AttributeError)
"""What pyserial and the OS raise when the line goes away."""


class LinkSettings(BaseModel):
    """Serial parameters, framing and timeouts of the link (defaults: the C500C front console port).

    57600 8N1 without flow control, output lines ending CR LF and echo on are seen in the firmware's
    sources [C]; that the host should end commands with CR is an assumption [A] (both C500 drivers do).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    baudrate: int = Field(57600, gt=0)
    bytesize: Literal[5, 6, 7, 8] = 8
    parity: Literal["N", "E", "O", "M", "S"] = "N"
    stopbits: float = Field(1, description="1, 1.5 or 2")
    xonxoff: bool = False
    rtscts: bool = False
    line_ending: str = Field("\r", min_length=1, description="what the host ends each command with")
    echo: bool = Field(True, description="the controller echoes what is typed")
    encoding: str = "ascii"
    reply_timeout_s: float = Field(3.0, gt=0, description="wait for the prompt after a query")
    home_timeout_s: float = Field(300.0, gt=0, description="wait for the prompt after home (home waits)")
    poll_s: float = Field(0.02, gt=0, description="read granularity; also the port's read timeout")
    resync_quiet_s: float = Field(0.05, ge=0, description="silence that ends a drain of stale input")


class SerialTransport:
    """Lines over pyserial: ``write_line``, ``read_until_prompt``, ``drain``; nothing about commands."""

    def __init__(
        self,
        port: str | serial.SerialBase,
        settings: LinkSettings | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.settings = settings or LinkSettings()
        self._clock = clock
        self._link = SerialPort(port)
        self.name = self._link.name
        self._pending = bytearray()  # read past a prompt: the start of the next answer

    # ---------------------------------------------------------------- open / close

    @property
    def is_open(self) -> bool:
        return self._link.is_open

    def open(self) -> None:
        """Open the port exclusively (a name or URL is opened with ``serial_for_url``).

        A second opener gets :class:`~station.devices.DeviceBusyError` ("in use").
        """
        if self.is_open:
            return
        s = self.settings
        self._link.open_with(s)
        log.debug("opened %s (%s %d%s%s)", self.name, s.baudrate, s.bytesize, s.parity, s.stopbits)

    def close(self) -> None:
        """Close the port; safe to call twice."""
        self._pending.clear()
        self._link.close()
        log.debug("closed %s", self.name)

    def _port(self) -> serial.SerialBase:
        return self._link.require(f"{self.name!r} is not open: connect() first")

    def _lost(self, exc: Exception) -> DeviceConnectionError:
        self.close()
        return DeviceConnectionError(
            f"lost the link to {self.name!r} ({exc}); check the cable and the controller,"
            " then connect() again"
        )

    def _closed_under_us(self, exc: Exception) -> DeviceConnectionError:
        return DeviceConnectionError(
            f"the port {self.name!r} was closed while in use ({type(exc).__name__}: {exc}); connect() again"
        )

    # ---------------------------------------------------------------- I/O

    def write_bytes(self, data: bytes) -> None:
        """Write raw bytes (control characters such as the stop byte)."""
        port = self._port()
        log.debug("-> %r", data)
        try:
            port.write(data)
            port.flush()
        except LINK_ERRORS as exc:
            raise self._lost(exc) from exc
        except CLOSED_UNDER_US as exc:
            raise self._closed_under_us(exc) from exc

    def write_line(self, text: str) -> None:
        """Write one command line, ended with the configured line ending."""
        log.debug("-> %r", text)
        port = self._port()
        try:
            port.write((text + self.settings.line_ending).encode(self.settings.encoding))
            port.flush()
        except LINK_ERRORS as exc:
            raise self._lost(exc) from exc
        except CLOSED_UNDER_US as exc:
            raise self._closed_under_us(exc) from exc

    def _read_some(self) -> bytes:
        port = self._port()
        try:
            waiting = port.in_waiting
            data: bytes = port.read(max(1, waiting))
        except LINK_ERRORS as exc:
            raise self._lost(exc) from exc
        except CLOSED_UNDER_US as exc:
            raise self._closed_under_us(exc) from exc
        return data

    def read_until_prompt(
        self,
        prompt: str,
        timeout_s: float,
        *,
        what: str = "",
        on_line: Callable[[str], float] | None = None,
        interrupted: Callable[[], bool] | None = None,
    ) -> list[str]:
        """Read up to the first ``prompt`` at the start of a line; return the lines before it.

        Lines are split on CR LF (a bare CR or LF is accepted too) and logged one by one. Bytes read
        past the prompt are kept for the next call. Raises DeviceTimeoutError when no prompt has come
        after ``timeout_s``. ``on_line`` sees each complete line as it arrives and returns seconds to
        add to the deadline (a wait the controller announced); once ``interrupted()`` is true the
        deadline shrinks to ``reply_timeout_s`` from then.
        """
        deadline = self._clock() + timeout_s
        raw, self._pending = self._pending, bytearray()
        prompt_bytes = prompt.encode(self.settings.encoding)
        seen_lines = 0
        cut_short = False
        while True:
            if on_line is not None:
                complete = _split_lines(raw.decode(self.settings.encoding, errors="replace"))
                if raw and raw[-1:] not in (b"\r", b"\n"):
                    complete = complete[:-1]
                for line in complete[seen_lines:]:
                    extra = on_line(line)
                    if extra > 0:
                        deadline = max(deadline, self._clock() + extra)
                seen_lines = max(seen_lines, len(complete))
            if interrupted is not None and not cut_short and interrupted():
                cut_short = True
                deadline = min(deadline, self._clock() + self.settings.reply_timeout_s)
            end = _find_prompt(raw, prompt_bytes)
            if end is not None:
                before = raw[: end - len(prompt_bytes)]
                self._pending = raw[end:]
                lines = _split_lines(before.decode(self.settings.encoding, errors="replace"))
                for line in lines:
                    log.debug("<- %r", line)
                log.debug("<- prompt %r", prompt)
                return lines
            if self._clock() >= deadline:
                got = raw.decode(self.settings.encoding, errors="replace")
                for line in _split_lines(got):
                    log.debug("<- %r (before timeout)", line)
                raise DeviceTimeoutError(
                    f"no prompt {prompt!r} from {self.name!r} within {timeout_s:.3g} s"
                    + (f" after {what!r}" if what else "")
                    + (f" (received {got[-120:]!r})" if got else " (received nothing)")
                    + f"; check the cable, {self.settings.baudrate} baud, and that the controller shows"
                    f" the {prompt!r} prompt"
                )
            raw += self._read_some()

    def drain(self) -> str:
        """Discard pending input until the line has been quiet for ``resync_quiet_s``; return it."""
        got, self._pending = self._pending, bytearray()
        quiet_until = self._clock() + self.settings.resync_quiet_s
        while self._clock() < quiet_until:
            chunk = self._read_some()  # blocks at most poll_s
            if chunk:
                got += chunk
                quiet_until = self._clock() + self.settings.resync_quiet_s
        text = got.decode(self.settings.encoding, errors="replace")
        if text:
            log.debug("<- discarded %r", text)
        return text


def _find_prompt(raw: bytearray, prompt: bytes) -> int | None:
    """End index of the first ``prompt`` that starts a line in ``raw``, or None."""
    start = 0
    while (i := raw.find(prompt, start)) >= 0:
        if i == 0 or raw[i - 1] in b"\r\n":
            return i + len(prompt)
        start = i + 1
    return None


def _split_lines(text: str) -> list[str]:
    """Split on CR LF, CR or LF; keep empty lines between line ends but drop the trailing empty one."""
    normalised = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = normalised.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    return lines


__all__ = ["LinkSettings", "SerialTransport"]
