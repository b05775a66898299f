"""Every reply of the C500C is parsed here, and nowhere else.

The row labels and number formats of the ``w0``/``w2`` tables, the speed and power texts are seen in
the firmware [C]; the column spacing is not known [A], so rows are split on whitespace and each number
must have the documented form (signed integer pulses; signed fixed-point joints and world values).
A line that fits nothing raises :class:`~station.devices.DeviceProtocolError`: a garbled reply never
becomes a number.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from drivers.crs_a465._errors import CrsControllerError, find_error
from station.devices import JOINT_COUNT, DeviceProtocolError

log = logging.getLogger(__name__)

PositionKind = Literal["commanded", "actual"]

_INT = r"[+-]?\d+"
_FIXED = r"[+-]?\d+\.\d+"
_HEADER = re.compile(r"^(?P<kind>Commanded|Actual) Position\s*:\s*$")
_AXIS_HEADER = re.compile(r"^\s*Axis 1/7\s+Axis 2/8\s+Axis 3\s+Axis 4\s+Axis 5\s+Axis 6\s*$")
_WORLD_HEADER = re.compile(r"^\s*X/TrackX\s+Y/TrackY\s+Z\s+Z-Rot\s+Y-Rot\s+X-Rot\s*$")
_WORLD_UNITS = re.compile(r"^WORLD\s+\(mm\)\s+\(mm\)\s+\(mm\)\s+\(deg\)\s+\(deg\)\s+\(deg\)\s*$")
_SPEED = re.compile(r"^Current Speed:\s*(?P<pct>\d+(?:\.\d+)?)% of max\.?\s*$")
_POWER = re.compile(r"^Arm Power is (?P<state>ON|OFF)\s*$")
_HOMED = re.compile(r"^Robot is calibrated and homed\s*$")
_NOT_HOMED = re.compile(r"^Robot is not (?:calibrated|homed)\b.*$")
_ARM_TYPE = re.compile(r"^Robot arm is of type (?P<type>\S+)\s*$")
_PRINTABLE = re.compile(r"^[\x20-\x7e\t]*$")


@dataclass(frozen=True)
class PositionReport:
    """A parsed ``w0`` or ``w2`` table: six arm axes, the two track axes, the WORLD row."""

    kind: PositionKind
    pulses: tuple[int, ...]
    joints_deg: tuple[float, ...]
    track_pulses: tuple[int, ...]
    track_deg: tuple[float, ...]
    world_mm_deg: tuple[float, ...]


@dataclass(frozen=True)
class ArmStat:
    """The ``armstat`` report; a part the controller did not print is ``None``."""

    power: bool | None
    homed: bool | None
    arm_type: str | None


def _garbled(command: str, detail: str, lines: Sequence[str]) -> DeviceProtocolError:
    shown = "\n".join(repr(line) for line in lines[:12])
    return DeviceProtocolError(
        f"unparsable reply to {command!r}: {detail}; the line may be noisy (check the cable and baud rate)."
        f" Reply was:\n{shown}"
    )


def check_printable(command: str, lines: Sequence[str]) -> None:
    """Raise DeviceProtocolError on non-printable characters: line noise, a wrong baud rate."""
    for line in lines:
        if not _PRINTABLE.match(line):
            raise _garbled(command, f"non-printable characters in {line!r}", lines)


def raise_for_error(command: str, lines: Sequence[str]) -> None:
    """Raise the typed controller error found in ``lines``, if any."""
    error: CrsControllerError | None = find_error(lines, command)
    if error is not None:
        raise error


def _numbers(
    line: str, label: str, pattern: str, count: int, command: str, lines: Sequence[str]
) -> list[str]:
    rest = line[len(label) :] if label else line
    fields = rest.split()
    if len(fields) != count or not all(re.fullmatch(pattern, f) for f in fields):
        raise _garbled(command, f"expected {count} numbers in {line!r}", lines)
    return fields


def parse_position(lines: Sequence[str], *, expect: PositionKind, command: str) -> PositionReport:
    """Parse the table printed by ``w0`` (``expect="commanded"``) or ``w2`` (``"actual"``)."""
    check_printable(command, lines)
    rows = [line for line in lines if line.strip()]
    i = 0

    def next_row(what: str) -> str:
        nonlocal i
        if i >= len(rows):
            raise _garbled(command, f"the table ends before its {what}", lines)
        row = rows[i]
        i += 1
        return row

    header = _HEADER.match(next_row("header"))
    if header is None or header.group("kind").lower() != expect:
        raise _garbled(command, f"expected a '{expect.capitalize()} Position :' table", lines)
    if not _AXIS_HEADER.match(next_row("axis header")):
        raise _garbled(command, "no 'Axis 1/7 ... Axis 6' header", lines)
    pulses_row = next_row("PULSES row")
    if not pulses_row.startswith("PULSES"):
        raise _garbled(command, "no PULSES row", lines)
    pulses = [int(v) for v in _numbers(pulses_row, "PULSES", _INT, JOINT_COUNT, command, lines)]
    track_pulses = [int(v) for v in _numbers(next_row("track pulses"), "", _INT, 2, command, lines)]
    joints_row = next_row("JOINTS row")
    if not joints_row.startswith("JOINTS"):
        raise _garbled(command, "no JOINTS row", lines)
    joints = [float(v) for v in _numbers(joints_row, "JOINTS", _FIXED, JOINT_COUNT, command, lines)]
    track = [float(v) for v in _numbers(next_row("track joints"), "", _FIXED, 2, command, lines)]
    if not _WORLD_HEADER.match(next_row("world header")):
        raise _garbled(command, "no 'X/TrackX ... X-Rot' header", lines)
    if not _WORLD_UNITS.match(next_row("WORLD row")):
        raise _garbled(command, "no 'WORLD (mm) ... (deg)' row", lines)
    world = [float(v) for v in _numbers(next_row("world values"), "", _FIXED, 6, command, lines)]
    if i != len(rows):
        raise _garbled(command, f"unexpected lines after the table: {rows[i:]!r}", lines)
    return PositionReport(
        kind=expect,
        pulses=tuple(pulses),
        joints_deg=tuple(joints),
        track_pulses=tuple(track_pulses),
        track_deg=tuple(track),
        world_mm_deg=tuple(world),
    )


def parse_speed(lines: Sequence[str], *, command: str = "speed") -> float:
    """Parse ``Current Speed: 50% of max.`` into percent."""
    check_printable(command, lines)
    found = [m for m in (_SPEED.match(line.strip()) for line in lines) if m]
    if len(found) != 1 or len([line for line in lines if line.strip()]) != 1:
        raise _garbled(command, "expected one 'Current Speed: N% of max.' line", lines)
    return float(found[0].group("pct"))


def parse_armstat(lines: Sequence[str], *, command: str = "armstat") -> ArmStat:
    """Parse the ``armstat`` report (power, homing, arm type); unknown printable lines are logged."""
    check_printable(command, lines)
    power: bool | None = None
    homed: bool | None = None
    arm_type: str | None = None
    for raw in lines:
        line = raw.strip()
        if not line:
            continue
        if m := _POWER.match(line):
            power = m.group("state") == "ON"
        elif _HOMED.match(line):
            homed = True
        elif _NOT_HOMED.match(line):
            homed = False
        elif m := _ARM_TYPE.match(line):
            arm_type = m.group("type")
        else:
            log.info("armstat: unrecognised line %r (ignored)", line)
    if power is None and homed is None and arm_type is None:
        raise _garbled(command, "no power, homing or arm-type line", lines)
    return ArmStat(power=power, homed=homed, arm_type=arm_type)


def check_silent(command: str, lines: Sequence[str]) -> None:
    """For commands that print nothing on success: reject noise, log any other text."""
    check_printable(command, lines)
    for line in lines:
        if line.strip():
            log.info("%s: controller said %r", command, line)


__all__ = [
    "ArmStat",
    "PositionKind",
    "PositionReport",
    "check_printable",
    "check_silent",
    "parse_armstat",
    "parse_position",
    "parse_speed",
    "raise_for_error",
]
