"""The DL-RS1A's ASCII dialect for IL series amplifiers: what is sent and how replies are read.

The one replaceable part of the driver: framing, command strings, reply parsing, error replies and the
readouts that are not distances. Pure functions, no I/O. What comes from the manual and what is assumed:
``drivers/keyence_il/DIALECT.md`` ([M] manual, [A] assumption).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

from station.devices import DeviceProtocolError

COMMAND_END = "\r\n"
"""[M] A command ends with CR or CR LF; the driver sends CR LF."""

REPLY_END = b"\r\n"
"""[M] Every reply, normal or error, ends with CR LF."""

MEASURE = "M0"
"""[M] Read the measured value (P.V.) of every amplifier on the DL-RS1A: ``M0`` -> ``M0,v00,v01,...``."""

#: [M] Error numbers of an ``ER,<command>,<nn>`` reply: name and what to do.
ERROR_NUMBERS: dict[str, tuple[str, str]] = {
    "00": ("invalid command", "the unit did not recognise the command; check the driver's dialect"),
    "20": ("data length error", "the command was not ended with CR or CR LF; check the line ending"),
    "21": ("number of parameters error", "the command had the wrong number of fields"),
    "22": ("parameter error", "a parameter was out of range, or the data number cannot be read"),
    "29": (
        "communication error",
        "the unit saw an RS-232C error; check that its baud rate, parity and stop bits (its setup"
        " switches) match the driver's settings, and the cable",
    ),
    "65": ("ID number error", "no amplifier with that ID is connected to the DL-RS1A"),
}

ReadoutKind = Literal["value", "above", "below", "invalid", "error"]

#: [M] IL-030/065/100 (and the S models) print the P.V. as ``±**.***`` (7 characters).
_VALUE = re.compile(r"^[+-]\d{2}\.\d{3}$")
_ERROR = "+EE.EEE"  # [M] the amplifier is in an error state
_ABOVE = "+99.999"  # [M] +99.999 or beyond the upper display range
_BELOW = "-99.999"  # [M] -99.999 or beyond the lower display range
_INVALID = re.compile(r"^[+-]FF\.FFF$")  # [A] the amplifier shows "-----" (no valid measurement)


class ErrorReplyError(DeviceProtocolError):
    """The DL-RS1A answered ``ER,<command>,<nn>``: it refused the command. ``code`` is ``nn``."""

    def __init__(self, message: str, *, code: str, reply: str) -> None:
        super().__init__(message)
        self.code = code
        self.reply = reply


@dataclass(frozen=True)
class Readout:
    """One amplifier's field of an ``M0`` reply: a displacement (mm) or one of the special readouts."""

    kind: ReadoutKind
    text: str
    value_mm: float | None = None


def encode(command: str) -> bytes:
    """The bytes of one command line."""
    return (command + COMMAND_END).encode("ascii")


def parse_reply(command: str, line: str) -> list[str]:
    """The fields after the echoed command of a reply to ``command`` (``M0,+01.234`` -> ``["+01.234"]``).

    Raises :class:`ErrorReplyError` on ``ER,...``, ``DeviceProtocolError`` on anything else that is not
    a reply to ``command``.
    """
    fields = line.split(",")
    if fields[0] == "ER":
        if len(fields) != 3 or fields[1] != command or not re.fullmatch(r"\d\d", fields[2]):
            raise DeviceProtocolError(f"malformed error reply {line!r} to {command!r}")
        code = fields[2]
        name, action = ERROR_NUMBERS.get(code, ("unknown error number", "see the DL-RS1A manual"))
        raise ErrorReplyError(
            f"the DL-RS1A refused {command!r}: error {code} ({name}): {action}", code=code, reply=line
        )
    if fields[0] != command or len(fields) < 2:
        raise DeviceProtocolError(f"unexpected reply {line!r} to {command!r} (expected {command},...)")
    return fields[1:]


def parse_readout(text: str) -> Readout:
    """Read one ``±**.***`` field; the special readouts keep their kind and no value."""
    if text == _ERROR:
        return Readout("error", text)
    if text == _ABOVE:
        return Readout("above", text)
    if text == _BELOW:
        return Readout("below", text)
    if _INVALID.match(text):
        return Readout("invalid", text)
    if not _VALUE.match(text):
        raise DeviceProtocolError(f"unreadable measured value {text!r} (expected ±**.***)")
    return Readout("value", text, float(text))


__all__ = [
    "COMMAND_END",
    "ERROR_NUMBERS",
    "MEASURE",
    "REPLY_END",
    "ErrorReplyError",
    "Readout",
    "ReadoutKind",
    "encode",
    "parse_readout",
    "parse_reply",
]
