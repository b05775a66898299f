"""The C500C's error texts, mapped once to typed exceptions with what the operator should do.

The firmware's programs print ``<program>: <text>``, where the text is a line of the controller's error
files without its number and with ``$1`` replaced by the axis; an unmapped code prints
``error code S:B2:B1:N``; argument errors print a message then ``Usage: ...``; the shell says
``shell: NAME: not found``; the robot server may print ``/sbin/robotsrv: <text> (error code 0x...)``
unprompted while a motion runs [inferred]. All of these are read from the firmware image (see
DIALECT.md). The application shell's ``Unrecognized command.``, ``error: <text>`` and RAPL-3 exception
forms are kept from the older sources. A number before a text (``007 Arm power is OFF``) is tolerated.

Matching is case-sensitive and anchored: a bare error text must be the whole line, so the armstat report
``Arm power is OFF     Robot is calibrated`` is a report, not an error.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
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


class StanceError(OutOfReachError):
    hint = "the motion is impossible in the arm's current stance: choose another pose or path"


class AxisLimpError(CrsControllerError):
    hint = "an axis is limp: make it rigid (nolimp) before moving"


class AxisLockedError(CrsControllerError):
    hint = "an axis is locked on the controller: unlock it before moving"


class NotHomedError(CrsControllerError):
    hint = "home the arm first (station robot ... home)"


class HomingError(CrsControllerError):
    hint = "homing failed: check arm power, the E-stop and the axis named, then home again"


class IllegalSpeedError(CrsControllerError):
    hint = "choose a speed between 1 and 100 percent"


class MotionFaultError(CrsControllerError):
    hint = "the controller stopped the motion: read the position (where), check the arm, then retry"


class MotionAbortedError(MotionFaultError):
    hint = "the motion was aborted (halt or abort): read the position (where) before going on"


class ServoError(MotionFaultError):
    hint = "a servo fault: check the axis named and its drive, re-enable arm power, read the position"


class CollisionError(ServoError):
    hint = "a servo reported a collision: clear the arm's path, check the axis, re-enable power"


class EncoderAlarmError(ServoError):
    hint = "an encoder alarm: the encoder batteries may be low; replace them and recalibrate"


class PointOfControlError(CrsControllerError):
    hint = "press PAUSE/CONTINUE on the pendant to give the serial port the point of control"


class LockedOutError(CrsControllerError):
    hint = "the command is locked out on the controller: release it from the pendant or the controller"


class NotOnlineError(CrsControllerError):
    hint = "put the controller in online mode (application shell: online on)"


class UnknownCommandError(CrsControllerError):
    hint = "the controller does not know this command: check the shell setting (system or application)"


class ControllerUsageError(CrsControllerError):
    hint = "the controller refused the command's arguments: a driver bug or a different firmware"


class ControllerBusyError(CrsControllerError):
    hint = "the controller is busy (resource temporarily unavailable): wait, then retry"


class CommandNotAvailableError(CrsControllerError):
    hint = "the command is not available in this state of the controller"


class UnmappedCodeError(CrsControllerError):
    hint = "an error code without a text: look it up in the controller's error files"


class RaplExceptionError(CrsControllerError):
    hint = "a RAPL-3 program raised an exception: read the controller's message"


class UnexpectedReplyError(CrsControllerError):
    hint = (
        "the controller printed something the driver does not know after a motion command: the"
        " command is treated as failed; read the position (where) before going on"
    )


class InvalidArgumentError(DeviceError, ValueError):
    """An argument failed validation on the host; nothing was sent."""


class ArrivalError(DeviceError):
    """The arm stopped, or is commanded, away from the target of a motion that raised no controller error."""


@dataclass(frozen=True)
class _ErrorText:
    pattern: re.Pattern[str]
    error: type[CrsControllerError]


_AXIS = r"(?P<axis>\d+)"


def _text(text: str) -> re.Pattern[str]:
    """An error-file text, its number optional (``$1`` already written as ``_AXIS``)."""
    return re.compile(r"(?:(?P<code>\d{3}) )?" + text + r"\.?")


ERROR_TEXTS: tuple[_ErrorText, ...] = (
    # subsystem 4: kinematics and path
    _ErrorText(_text(rf"Joint {_AXIS} limit exceeded"), JointLimitError),
    _ErrorText(_text(r"Location out of reach"), OutOfReachError),
    _ErrorText(_text(rf"Axis {_AXIS} is limp"), AxisLimpError),
    _ErrorText(_text(r"Not homed or not calibrated"), NotHomedError),
    _ErrorText(_text(r"Arm power is OFF"), ArmPowerOffError),
    _ErrorText(_text(rf"Axis {_AXIS} is locked"), AxisLockedError),
    _ErrorText(_text(r"Motion error"), MotionFaultError),
    _ErrorText(_text(r"Abort in progress"), MotionAbortedError),
    _ErrorText(_text(r"Illegal speed chosen"), IllegalSpeedError),
    _ErrorText(_text(r"Illegal axis"), ControllerUsageError),
    _ErrorText(_text(r"Command not available"), CommandNotAvailableError),
    _ErrorText(_text(r"Homing sequence error"), HomingError),
    _ErrorText(_text(r"Cannot perform requested motion in current stance"), StanceError),
    _ErrorText(_text(rf"Axis {_AXIS} velocity limit exceeded"), MotionFaultError),
    _ErrorText(_text(rf"Axis {_AXIS} acceleration limit exceeded"), MotionFaultError),
    _ErrorText(_text(r"Halt\(\) command invoked"), MotionAbortedError),
    # subsystem 2: robot server
    _ErrorText(_text(r"This command has been locked out"), LockedOutError),
    _ErrorText(_text(rf"Axis {_AXIS} was too far from the expected position"), MotionFaultError),
    # subsystem 7: servo
    _ErrorText(_text(rf"Axis {_AXIS} overspeed error"), ServoError),
    _ErrorText(_text(rf"Runaway error on axis {_AXIS}"), ServoError),
    _ErrorText(_text(rf"Excessive lag error on axis {_AXIS}"), ServoError),
    _ErrorText(_text(rf"Collision error on axis {_AXIS}"), CollisionError),
    _ErrorText(_text(rf"Axis {_AXIS} encoder alarm -- batteries may be low"), EncoderAlarmError),
    _ErrorText(_text(rf"Amp disabled on axis {_AXIS}"), ServoError),
    # subsystem 0: kernel
    _ErrorText(re.compile(r"(?P<name>.+): not found"), UnknownCommandError),
    _ErrorText(_text(r"not found"), UnknownCommandError),
    _ErrorText(_text(r"too many arguments"), ControllerUsageError),
    _ErrorText(_text(r"access denied"), PointOfControlError),
    _ErrorText(_text(r"invalid argument"), ControllerUsageError),
    _ErrorText(_text(r"resource temporarily unavailable"), ControllerBusyError),
    # argument checks of the programs
    _ErrorText(re.compile(r"[Ii]nvalid command line arguments\."), ControllerUsageError),
    _ErrorText(re.compile(r"Invalid axis '[^']*'"), ControllerUsageError),
    _ErrorText(re.compile(r"Invalid distance '[^']*'"), ControllerUsageError),
    _ErrorText(re.compile(r"invalid speed '[^']*'"), IllegalSpeedError),
    _ErrorText(re.compile(r"illegal axis number '[^']*'"), ControllerUsageError),
    _ErrorText(re.compile(r"error code (?P<codes>\d+:\d+:\d+:\d+)"), UnmappedCodeError),
    # application shell and older sources
    _ErrorText(
        re.compile(r"Press the PAUSE/CONTINUE button to gain robot point of control\.?"), PointOfControlError
    ),
    _ErrorText(re.compile(r"Robot must be in online mode for this command\.?"), NotOnlineError),
    _ErrorText(re.compile(r"Unrecognized command\."), UnknownCommandError),
)
"""Every controller error text the driver knows, in one place; first match wins."""

_PROGRAM = re.compile(r"^(?P<program>[A-Za-z0-9_./-]+): (?P<text>.*?)\s*$")
"""``<program>: <text>`` (``joint: Joint 2 limit exceeded``, ``/sbin/robotsrv: ...``, ``error: ...``)."""
_SERVER_CODE = re.compile(r"\s*\(error code 0x[0-9A-Fa-f]+\)\s*$")
_USAGE = re.compile(r"^Usage: ")
_RAPL_EXCEPTION = re.compile(r"Process \d+: exception raised \(code = '(?P<text>[^']*)'\)")

HALT_NOTICE = re.compile(r"\^Z detected - halting robot")
"""The robot server's halt message (``/sbin/robotsrv: ^Z detected - halting robot...``) [F]."""
POINT_OF_CONTROL = re.compile(r"^Press the PAUSE/CONTINUE button to gain robot point of control\.?\s*$")
"""The teach pendant holds control: the program waits for the button, it has not failed [F]."""


def _lookup(text: str) -> tuple[type[CrsControllerError], int | None, int | None] | None:
    for entry in ERROR_TEXTS:
        m = entry.pattern.fullmatch(text)
        if m is None:
            continue
        groups = m.groupdict()
        code = int(groups["code"]) if groups.get("code") else None
        axis = int(groups["axis"]) if groups.get("axis") else None
        return entry.error, code, axis
    return None


def error_of_line(line: str, command: str = "") -> CrsControllerError | None:
    """The controller error one reply line reports, or None when the line is no known error form."""
    text = line.strip()
    if not text:
        return None
    m = _PROGRAM.match(text)
    if m is not None:
        inner = _SERVER_CODE.sub("", m.group("text"))
        if HALT_NOTICE.search(inner):
            return None  # a halt notice, handled by the motion code
        known = _lookup(inner)
        if known is not None:
            error, code, axis = known
            return error(text, code=code, axis=axis, command=command)
        program = m.group("program")
        own = command.split()[0] if command.split() else ""
        if program in {"error", "shell", own} or program.startswith("/"):
            return CrsControllerError(text, command=command)
        return None  # 'word: text' the driver does not know: the caller decides
    if _USAGE.match(text):
        return ControllerUsageError(text, command=command)
    known = _lookup(text)
    if known is not None:
        error, code, axis = known
        return error(text, code=code, axis=axis, command=command)
    return None


def find_error(lines: Iterable[str], command: str = "") -> CrsControllerError | None:
    """The first controller error found in reply ``lines`` (None when there is none).

    A ``Usage:`` line after the error is kept in its ``controller_text``; a RAPL-3 exception keeps its
    ``in module`` line.
    """
    lines = list(lines)
    for i, line in enumerate(lines):
        m = _RAPL_EXCEPTION.search(line)
        if m is not None:
            text = " ".join(s.strip() for s in lines[i : i + 2])  # the exception and its "in module" line
            known = _lookup(m.group("text"))
            if known is not None:
                kind, code, axis = known
                return kind(text, code=code, axis=axis, command=command)
            return RaplExceptionError(text, command=command)
        found = error_of_line(line, command)
        if found is not None:
            following = lines[i + 1].strip() if i + 1 < len(lines) else ""
            if _USAGE.match(following) and not _USAGE.match(line.strip()):
                return type(found)(
                    f"{line.strip()} {following}", code=found.code, axis=found.axis, command=command
                )
            return found
    return None


def unexpected(command: str, lines: Sequence[str]) -> UnexpectedReplyError:
    """Text after a motion command that is neither known progress nor a known error."""
    shown = " | ".join(line.strip() for line in lines if line.strip())
    return UnexpectedReplyError(shown, command=command)


def rejected(message: str) -> MotionRejectedError:
    """A host-side rejection: the message says what was wrong and that nothing was sent."""
    return MotionRejectedError(f"{message}; nothing was sent to the controller")


__all__ = [
    "ERROR_TEXTS",
    "HALT_NOTICE",
    "POINT_OF_CONTROL",
    "ArmPowerOffError",
    "ArrivalError",
    "AxisLimpError",
    "AxisLockedError",
    "CollisionError",
    "CommandNotAvailableError",
    "ControllerBusyError",
    "ControllerUsageError",
    "CrsControllerError",
    "EncoderAlarmError",
    "HomingError",
    "IllegalSpeedError",
    "InvalidArgumentError",
    "JointLimitError",
    "LockedOutError",
    "MotionAbortedError",
    "MotionFaultError",
    "NotHomedError",
    "NotOnlineError",
    "OutOfReachError",
    "PointOfControlError",
    "RaplExceptionError",
    "ServoError",
    "StanceError",
    "UnexpectedReplyError",
    "UnknownCommandError",
    "UnmappedCodeError",
    "error_of_line",
    "find_error",
    "rejected",
    "unexpected",
]
