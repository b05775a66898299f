"""The C500C's error texts, mapped once to typed exceptions with what the operator should do.

Sources (docs/crs-c500c-protocol.md): the numbered kinematics and servo texts (``001 Joint $1 limit
exceeded`` ...), the RAPL-3 runtime exception form (``Process 193: exception raised (code = '...')``),
the application shell's ``Unrecognized command.`` and the point-of-control messages are all seen in
the C500C firmware [C]. Where a text appears in a reply (with or without a ``PROGRAM: `` or ``error: ``
prefix, with or without its number) is not known, so every reply line is searched for every text.
Matching is case-sensitive on purpose: ``Arm power is OFF`` is an error, ``Arm Power is OFF`` a report.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

from station.devices import ControllerError, DeviceError, MotionRejectedError


class CrsControllerError(ControllerError):
    """The C500C refused or failed a command (base of the errors below)."""

    hint = "see the controller's message"

    def __init__(
        self, controller_text: str, *, code: int | None = None, axis: int | None = None, command: str = ""
    ) -> None:
        where = f" (command {command!r})" if command else ""
        super().__init__(
            f"controller: {controller_text}{where}: {self.hint}", controller_text=controller_text, code=code
        )
        self.axis = axis
        self.command = command


class ArmPowerOffError(CrsControllerError):
    hint = "switch arm power on (ARM POWER on the controller or pendant), then retry"


class JointLimitError(CrsControllerError):
    hint = "the controller's limits are narrower than the host's: narrow the station's joint limits"


class OutOfReachError(CrsControllerError):
    hint = "the location is out of reach: choose a pose inside the work envelope"


class AxisLimpError(CrsControllerError):
    hint = "an axis is limp: make it rigid (nolimp) before moving"


class NotHomedError(CrsControllerError):
    hint = "home the arm first (station robot ... home)"


class IllegalSpeedError(CrsControllerError):
    hint = "choose a speed between 1 and 100 percent"


class CollisionError(CrsControllerError):
    hint = "a servo reported a collision: clear the arm's path, check the axis, re-enable power"


class PointOfControlError(CrsControllerError):
    hint = "press PAUSE/CONTINUE on the pendant to give the serial port the point of control"


class NotOnlineError(CrsControllerError):
    hint = "put the controller in online mode (application shell: online on)"


class UnknownCommandError(CrsControllerError):
    hint = "the controller does not know this command: check the shell setting (system or application)"


class RaplExceptionError(CrsControllerError):
    hint = "a RAPL-3 program raised an exception: read the controller's message"


class InvalidArgumentError(DeviceError, ValueError):
    """An argument failed validation on the host; nothing was sent."""


@dataclass(frozen=True)
class _ErrorText:
    pattern: re.Pattern[str]
    error: type[CrsControllerError]


def _numbered(text: str) -> re.Pattern[str]:
    """A numbered kinematics/servo text, number optional (RAPL-3 exceptions quote it without)."""
    return re.compile(r"(?:(?P<code>\d{3}) )?" + text)


ERROR_TEXTS: tuple[_ErrorText, ...] = (
    _ErrorText(_numbered(r"Joint (?P<axis>\d+) limit exceeded"), JointLimitError),
    _ErrorText(_numbered(r"Location out of reach"), OutOfReachError),
    _ErrorText(_numbered(r"Axis (?P<axis>\d+) is limp"), AxisLimpError),
    _ErrorText(_numbered(r"Not homed or not calibrated"), NotHomedError),
    _ErrorText(_numbered(r"Arm power is OFF"), ArmPowerOffError),
    _ErrorText(_numbered(r"Illegal speed chosen"), IllegalSpeedError),
    _ErrorText(_numbered(r"Collision error on axis (?P<axis>\d+)"), CollisionError),
    _ErrorText(
        re.compile(r"Press the PAUSE/CONTINUE button to gain robot point of control"), PointOfControlError
    ),
    _ErrorText(re.compile(r"Robot must be in online mode for this command"), NotOnlineError),
    _ErrorText(re.compile(r"Unrecognized command\."), UnknownCommandError),
    _ErrorText(re.compile(r"(?:Command )?not found\.?$"), UnknownCommandError),
)
"""Every controller error text the driver knows, in one place; first match wins."""

_RAPL_EXCEPTION = re.compile(r"Process \d+: exception raised \(code = '(?P<text>[^']*)'\)")


def _match_text(text: str, command: str) -> CrsControllerError | None:
    for entry in ERROR_TEXTS:
        m = entry.pattern.search(text)
        if m is None:
            continue
        groups = m.groupdict()
        code = int(groups["code"]) if groups.get("code") else None
        axis = int(groups["axis"]) if groups.get("axis") else None
        return entry.error(text.strip(), code=code, axis=axis, command=command)
    return None


def find_error(lines: Iterable[str], command: str = "") -> CrsControllerError | None:
    """The first controller error found in reply ``lines`` (None when there is none)."""
    lines = list(lines)
    for i, line in enumerate(lines):
        m = _RAPL_EXCEPTION.search(line)
        if m is not None:
            text = " ".join(s.strip() for s in lines[i : i + 2])  # the exception and its "in module" line
            known = _match_text(m.group("text"), command)
            if known is not None:
                return type(known)(text, code=known.code, axis=known.axis, command=command)
            return RaplExceptionError(text, command=command)
        error = _match_text(line, command)
        if error is not None:
            return error
    return None


def rejected(message: str) -> MotionRejectedError:
    """A host-side rejection: the message says what was wrong and that nothing was sent."""
    return MotionRejectedError(f"{message}; nothing was sent to the controller")


__all__ = [
    "ERROR_TEXTS",
    "ArmPowerOffError",
    "AxisLimpError",
    "CollisionError",
    "CrsControllerError",
    "IllegalSpeedError",
    "InvalidArgumentError",
    "JointLimitError",
    "NotHomedError",
    "NotOnlineError",
    "OutOfReachError",
    "PointOfControlError",
    "RaplExceptionError",
    "UnknownCommandError",
    "find_error",
    "rejected",
]
