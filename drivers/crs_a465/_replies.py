"""Every reply of the C500C is parsed here, and nowhere else.

Position tables (``w0``/``w2``) are parsed by their labelled rows, not by line positions: the firmware's
system shell repeats the axis header before each row, prints no units row and puts WORLD's values on
the WORLD line [F]; the application shell's layout (a ``WORLD (mm) ... (deg)`` units row with the values
on the next line) is an assumption kept from older notes. Both parse: blank lines and axis headers are
skipped, values may be on the label's line or the next, and the two-value row that follows a row (axes
7-8, or the track) is optional. Column spacing is ignored; every number must have its documented form
(signed integer pulses; signed fixed-point joints and world values). A line that fits nothing raises
:class:`~station.devices.DeviceProtocolError`: a garbled reply never becomes a number.
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
_TITLE = re.compile(r"^(?P<kind>Commanded|Actual) Position\s*:\s*$")
_AXIS_HEADER = re.compile(r"^\s*Axis 1/7\s+Axis 2/8\s+Axis 3\s+Axis 4\s+Axis 5\s+Axis 6\s*$")
_WORLD_HEADER = re.compile(r"^\s*X/TrackX\s+Y/TrackY\s+Z\s+Z-Rot\s+Y-Rot\s+X-Rot\s*$")
_UNITS = re.compile(r"^(?:\((?:mm|deg)\)\s*){6}$")
_ROW = re.compile(r"^(?P<label>PULSES|JOINTS|WORLD)\b\s*(?P<rest>.*)$")
_SPEED = re.compile(r"^Current Speed:\s*(?P<pct>\d+)% of max\.?$|^Current speed is (?P<pct2>\d+)\.?$")
_ARM_TYPE = re.compile(r"^Robot arm is of type (?P<type>\S+)$")
_POWER = re.compile(r"^Arm [Pp]ower is (?P<state>ON|OFF)\b\s*(?P<rest>.*)$")
_HOMING = {
    "Robot is calibrated and homed": (True, True),
    "Robot is calibrated": (True, False),
    "Robot is not homed": (None, False),
    "Robot is not calibrated": (False, False),
}
"""armstat's homing texts -> (calibrated, homed) [F]."""
_AXIS_TABLE_HEADER = re.compile(r"^Axis\s+locked\s+done\s+limped\s+homed$")
_AXIS_ROW = re.compile(
    r"^(?P<axis>\d+)\s+(?P<locked>[YN])\s+(?P<done>[YN])\s+(?P<limped>[YN])\s+(?P<homed>[YN])$"
)
_ARMSTAT_KNOWN = (
    re.compile(r"^Units are \S+\s+Online is (?:ON|OFF)$"),
    re.compile(r"^Physical stance:.*$"),
    re.compile(r"^Current (?:Tool|Base) Transform is:$"),
    re.compile(r"^(?:t|w)x=[-+\d.]+, .*$"),
)
_PRINTABLE = re.compile(r"^[\x20-\x7e\t]*$")


@dataclass(frozen=True)
class PositionReport:
    """A parsed ``w0`` or ``w2`` table: six arm axes, the WORLD row, and the axes 7-8 rows if printed."""

    kind: PositionKind
    pulses: tuple[int, ...]
    joints_deg: tuple[float, ...]
    world_mm_deg: tuple[float, ...]
    track_pulses: tuple[int, ...] = ()
    track_deg: tuple[float, ...] = ()
    track_world: tuple[float, ...] = ()


@dataclass(frozen=True)
class AxisState:
    """One row of armstat's axis table."""

    axis: int
    locked: bool
    done: bool
    limped: bool
    homed: bool


@dataclass(frozen=True)
class ArmStat:
    """The ``armstat`` report; a part the controller did not print is ``None`` (or empty)."""

    power: bool | None
    homed: bool | None
    arm_type: str | None
    calibrated: bool | None = None
    axes: tuple[AxisState, ...] = ()

    @property
    def moving(self) -> bool | None:
        """True while any axis is not done; None when no axis table was printed."""
        if not self.axes:
            return None
        return not all(a.done for a in self.axes)


def _garbled(command: str, detail: str, lines: Sequence[str]) -> DeviceProtocolError:
    shown = "\n".join(repr(line) for line in lines[:16])
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


_ROW_FORMS = {"PULSES": (_INT, JOINT_COUNT), "JOINTS": (_FIXED, JOINT_COUNT), "WORLD": (_FIXED, 6)}


def _values(text: str, pattern: str, count: int) -> list[str] | None:
    fields = text.split()
    if len(fields) != count or not all(re.fullmatch(pattern, f) for f in fields):
        return None
    return fields


def parse_position(lines: Sequence[str], *, expect: PositionKind, command: str) -> PositionReport:
    """Parse the table printed by ``w0`` (``expect="commanded"``) or ``w2`` (``"actual"``), by row labels."""
    check_printable(command, lines)
    rows = [line.strip() for line in lines if line.strip()]
    if not rows:
        raise _garbled(command, "the reply is empty", lines)
    title = _TITLE.match(rows[0])
    if title is None or title.group("kind").lower() != expect:
        raise _garbled(command, f"expected a '{expect.capitalize()} Position :' table", lines)
    main: dict[str, list[str]] = {}
    track: dict[str, list[str]] = {}
    waiting: str | None = None  # a label whose values come on the next line
    last: str | None = None  # the label of the last complete row (its 7-8 row may follow)
    for row in rows[1:]:
        if _AXIS_HEADER.match(row) or _WORLD_HEADER.match(row):
            if waiting is not None:
                raise _garbled(command, f"no values after the {waiting} label", lines)
            last = None
            continue
        labelled = _ROW.match(row)
        if labelled is not None:
            label, rest = labelled.group("label"), labelled.group("rest").strip()
            if label in main or waiting is not None:
                raise _garbled(command, f"unexpected {label} row", lines)
            if not rest or _UNITS.match(rest):
                waiting, last = label, None
                continue
            pattern, count = _ROW_FORMS[label]
            values = _values(rest, pattern, count)
            if values is None:
                raise _garbled(command, f"expected {count} numbers in {row!r}", lines)
            main[label], last = values, label
            continue
        if waiting is not None:
            pattern, count = _ROW_FORMS[waiting]
            values = _values(row, pattern, count)
            if values is None:
                raise _garbled(command, f"expected {count} numbers of {waiting} in {row!r}", lines)
            main[waiting], last, waiting = values, waiting, None
            continue
        if last is not None and last not in track:
            pattern, _ = _ROW_FORMS[last]
            values = _values(row, pattern, 2)
            if values is None:
                raise _garbled(command, f"expected the axes 7-8 values of {last} in {row!r}", lines)
            track[last], last = values, None
            continue
        raise _garbled(command, f"unexpected line {row!r}", lines)
    missing = [label for label in ("PULSES", "JOINTS", "WORLD") if label not in main]
    if waiting is not None or missing:
        raise _garbled(command, f"the table ends before its {', '.join(missing) or waiting} row", lines)
    return PositionReport(
        kind=expect,
        pulses=tuple(int(v) for v in main["PULSES"]),
        joints_deg=tuple(float(v) for v in main["JOINTS"]),
        world_mm_deg=tuple(float(v) for v in main["WORLD"]),
        track_pulses=tuple(int(v) for v in track.get("PULSES", [])),
        track_deg=tuple(float(v) for v in track.get("JOINTS", [])),
        track_world=tuple(float(v) for v in track.get("WORLD", [])),
    )


def parse_speed(lines: Sequence[str], *, command: str = "speed") -> float:
    """Parse ``Current Speed: 25% of max.`` (system shell) or ``Current speed is 25`` into percent."""
    check_printable(command, lines)
    texts = [line.strip() for line in lines if line.strip()]
    found = [m for m in (_SPEED.match(t) for t in texts) if m]
    if len(found) != 1 or len(texts) != 1:
        raise _garbled(command, "expected one 'Current Speed: N% of max.' line", lines)
    return float(found[0].group("pct") or found[0].group("pct2"))


def parse_armstat(lines: Sequence[str], *, command: str = "armstat") -> ArmStat:
    """Parse the ``armstat`` report: arm type, power, calibration and homing, the per-axis table."""
    check_printable(command, lines)
    power: bool | None = None
    homed: bool | None = None
    calibrated: bool | None = None
    arm_type: str | None = None
    axes: list[AxisState] = []
    for raw in lines:
        line = raw.strip()
        if not line or _AXIS_TABLE_HEADER.match(line) or any(p.match(line) for p in _ARMSTAT_KNOWN):
            continue
        if m := _POWER.match(line):
            power = m.group("state") == "ON"
            rest = m.group("rest").strip()
            if rest:
                if rest not in _HOMING:
                    raise _garbled(command, f"unknown homing state {rest!r}", lines)
                calibrated, homed = _HOMING[rest]
        elif line in _HOMING:  # on a line of its own (older notes)
            calibrated, homed = _HOMING[line]
        elif m := _ARM_TYPE.match(line):
            arm_type = m.group("type")
        elif m := _AXIS_ROW.match(line):
            axes.append(
                AxisState(
                    axis=int(m.group("axis")),
                    locked=m.group("locked") == "Y",
                    done=m.group("done") == "Y",
                    limped=m.group("limped") == "Y",
                    homed=m.group("homed") == "Y",
                )
            )
        else:
            log.info("armstat: unrecognised line %r (ignored)", line)
    if power is None and homed is None and arm_type is None:
        raise _garbled(command, "no power, homing or arm-type line", lines)
    return ArmStat(power=power, homed=homed, arm_type=arm_type, calibrated=calibrated, axes=tuple(axes))


def check_silent(command: str, lines: Sequence[str]) -> None:
    """For commands that print nothing on success: reject noise, log any other text."""
    check_printable(command, lines)
    for line in lines:
        if line.strip():
            log.info("%s: controller said %r", command, line)


__all__ = [
    "ArmStat",
    "AxisState",
    "PositionKind",
    "PositionReport",
    "check_printable",
    "check_silent",
    "parse_armstat",
    "parse_position",
    "parse_speed",
    "raise_for_error",
]
