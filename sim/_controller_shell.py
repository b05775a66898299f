"""The twin's command interpreters: the C500C system shell (``$ ``) and the application shell (``NAME> ``).

Pure text in, text out: :meth:`Shell.execute` takes one typed line and returns the reply lines and how
long the arm will move. The pty server (``sim.controller``) adds echo, prompt, timing and faults.
The system shell's texts are the firmware's own format strings (drivers/crs_a465/DIALECT.md, "confirmed
by the firmware"): position tables with the axis header repeated and no units row, ``<program>: <text>``
errors without their numbers, ``Usage:`` lines, ``shell: NAME: not found``, armstat with power and homing
on one line. The application shell's layouts are not public: where the twin chooses, it says so [A].
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from sim._controller_arm import JOINTS, Arm, ArmError
from station.kinematics import world_row

log = logging.getLogger(__name__)

ShellKind = Literal["system", "application"]

AXIS_HEADER = "          Axis 1/7   Axis 2/8     Axis 3     Axis 4     Axis 5     Axis 6"
WORLD_HEADER = "          X/TrackX   Y/TrackY          Z      Z-Rot      Y-Rot      X-Rot"
WORLD_UNITS = "WORLD         (mm)       (mm)       (mm)      (deg)      (deg)      (deg)"
HALT_LINE = "/sbin/robotsrv: ^Z detected - halting robot..."
"""What the robot server prints when it halts the robot [F]."""


def _row(label: str, values: list[str]) -> str:
    """An 8-character label, then values of width 10 separated by one space [F]."""
    return f"{label:<8}" + " ".join(f"{v:>10}" for v in values)


def position_table(
    title: str, joints_deg: npt.NDArray[np.float64], pulses: list[int], world: tuple[float, ...]
) -> list[str]:
    """The system shell's ``w0``/``w2`` table, as the firmware prints it [F]."""
    track_int = [f"{0:+d}"] * 2
    track_fixed = [f"{0.0:+.3f}"] * 2
    return [
        f"{title} :",
        "",
        AXIS_HEADER,
        _row("PULSES", [f"{p:+d}" for p in pulses]),
        _row("", track_int),
        "",
        AXIS_HEADER,
        _row("JOINTS", [f"{v:+.3f}" for v in joints_deg]),
        _row("", track_fixed),
        "",
        WORLD_HEADER,
        _row("WORLD", [f"{v:+.3f}" for v in world]),
        _row("", track_fixed),
    ]


def application_position_table(
    title: str, joints_deg: npt.NDArray[np.float64], pulses: list[int], world: tuple[float, ...]
) -> list[str]:
    """The application shell's table [A: no public text of it is known; a units row, values below it]."""
    return [
        f"{title} :",
        AXIS_HEADER,
        "PULSES  " + "".join(f"{p:+11d}" for p in pulses),
        "        " + "".join(f"{0:+11d}" for _ in range(2)),
        "JOINTS  " + "".join(f"{v:+11.3f}" for v in joints_deg),
        "        " + "".join(f"{0.0:+11.3f}" for _ in range(2)),
        WORLD_HEADER,
        WORLD_UNITS,
        "        " + "".join(f"{v:+11.3f}" for v in world),
    ]


@dataclass
class Outcome:
    """What one command line produced: reply lines, and the real seconds until its motion ends."""

    lines: list[str] = field(default_factory=list)
    motion_s: float = 0.0
    is_motion: bool = False
    waits: bool = False  # the program waits for its motion (home) whatever the twin's mode
    after: list[str] = field(default_factory=list)  # printed once the motion has ended (home's lines)


class Shell:
    """One interpreter over an :class:`Arm`; ``kind`` selects the dialect."""

    def __init__(self, arm: Arm, *, kind: ShellKind = "system", app_name: str = "ash") -> None:
        self.arm = arm
        self.kind = kind
        self.app_name = app_name
        self._commands: dict[str, Callable[[list[str]], Outcome]] = {
            "home": self._home,
            "ready": self._ready,
            "joint": self._joint,
            "speed": self._speed,
            "w0": self._w0,
            "wcmd": self._w0,
            "w2": self._w2,
            "wact": self._w2,
            "limp": self._limp,
            "nolimp": self._nolimp,
            "calrdy": self._calrdy,
        }
        self._commands["armstat"] = self._armstat  # on both shells [F]
        if kind == "application":
            self._commands.update({"armpower": self._armpower, "finish": self._finish})

    @property
    def prompt(self) -> str:
        return "$ " if self.kind == "system" else f"{self.app_name}> "

    def _error(self, program: str, text: str) -> Outcome:
        # System shell programs print '<program>: <text>', the error file's line without its number [F];
        # the application shell 'error: <text>' [A].
        text = re.sub(r"^\d{3} ", "", text)
        return Outcome([f"{program}: {text}" if self.kind == "system" else f"error: {text}"])

    def _unknown(self, name: str) -> Outcome:
        if self.kind == "system":
            return Outcome([f"shell: {name}: not found"])  # [F]
        return Outcome(["error: Unrecognized command."])  # [A]

    def _args(self, rest: str) -> list[str]:
        if not rest.strip():
            return []
        if self.kind == "system":
            return rest.split()
        return [a.strip() for a in rest.split(",")]

    def is_motion(self, line: str) -> bool:
        """Whether ``line`` starts a motion (the server waits for the arm before it runs one)."""
        return line.strip().split(" ", 1)[0] in {"home", "ready", "joint"}

    def execute(self, line: str) -> Outcome:
        """Run one typed line (without its line ending)."""
        text = line.strip()
        if not text:
            return Outcome()
        name, _, rest = text.partition(" ")
        handler = self._commands.get(name)
        if handler is None:
            return self._unknown(name)
        try:
            return handler(self._args(rest))
        except ArmError as exc:
            return self._error(name, exc.text)
        except _UsageError as exc:
            return Outcome([exc.message, f"Usage: {exc.usage}"])

    # ---------------------------------------------------------------- reports

    def _table(self, title: str, joints: npt.NDArray[np.float64], pulses: list[int]) -> Outcome:
        world = world_row(self.arm.kinematics.flange(joints))
        layout = position_table if self.kind == "system" else application_position_table
        return Outcome(layout(title, joints, pulses, world))

    def _w0(self, args: list[str]) -> Outcome:
        _no_args(args, "w0")
        q = self.arm.commanded()
        return self._table("Commanded Position", q, self.arm.pulses(q))

    def _w2(self, args: list[str]) -> Outcome:
        _no_args(args, "w2")
        exact = self.arm.actual_exact()
        pulses = self.arm.pulses(exact)
        q = np.asarray(pulses, dtype=float) / np.asarray(self.arm.params.counts_per_deg)
        return self._table("Actual Position", q, pulses)

    def _speed(self, args: list[str]) -> Outcome:
        if not args:
            if self.kind == "application":
                return Outcome([f"Current speed is {self.arm.speed_pct}"])  # [C]
            return Outcome([f"Current Speed: {self.arm.speed_pct}% of max."])  # [F]
        usage = "speed [newspeed]"
        if len(args) != 1:
            raise _UsageError("speed: invalid command line arguments.", usage)
        if not re.fullmatch(r"\d+", args[0]) or not 1 <= int(args[0]) <= 100:
            raise _UsageError(f"speed: invalid speed '{args[0]}'", usage)  # whole numbers 1-100 [F]
        self.arm.speed_pct = int(args[0])
        return Outcome()  # a successful set prints nothing [F]

    def _armstat(self, args: list[str]) -> Outcome:
        """The firmware's armstat report [F]; the homing texts for each state [F]."""
        _no_args(args, "armstat")
        homing = "Robot is calibrated and homed" if self.arm.homed else "Robot is not homed"
        done = self.arm.axes_done()
        rows = [
            f"{axis:>2}        N       {'Y' if done[axis - 1] else 'N'}       "
            f"{'Y' if axis in self.arm.limp else 'N'}       {'Y' if self.arm.homed else 'N'}"
            for axis in range(1, JOINTS + 1)
        ]
        return Outcome(
            [
                "",
                "Robot arm is of type A465",
                f"{'Arm power is ' + ('ON' if self.arm.power else 'OFF'):<21}{homing}",
                "Units are Metric     Online is OFF",
                "Physical stance: free free free",
                "",
                "",
                "Current Tool Transform is: ",
                "tx=0.00000, ty=0.00000, tz=0.00000, yaw=0.00000, pitch=0.00000, roll=0.00000",
                "",
                "Current Base Transform is: ",
                "wx=0.00000, wy=0.00000, wz=0.00000, xrot=0.00000, yrot=0.00000, zrot=0.00000",
                "",
                "Axis    locked   done   limped   homed",
                *rows,
                "",
            ]
        )

    # ---------------------------------------------------------------- actions

    def _joint(self, args: list[str]) -> Outcome:
        usage = "joint joint distance"  # [F]
        if len(args) != 2:
            raise _UsageError("Invalid command line arguments.", usage)
        if not re.fullmatch(r"\d+", args[0]) or not 1 <= int(args[0]) <= JOINTS:
            raise _UsageError(f"Invalid axis '{args[0]}'", usage)
        try:
            degrees = float(args[1])
        except ValueError:
            raise _UsageError(f"Invalid distance '{args[1]}'", usage) from None
        if not math.isfinite(degrees):
            raise _UsageError(f"Invalid distance '{args[1]}'", usage)
        return Outcome(motion_s=self.arm.move_joint(int(args[0]), degrees), is_motion=True)

    def _home(self, args: list[str]) -> Outcome:
        """``home`` waits for its motion and prints one line per axis [F; the seek part: inferred]."""
        for a in args:
            if not re.fullmatch(r"\d+", a) or not 1 <= int(a) <= JOINTS:
                raise _UsageError(f"home: illegal axis number '{a}'", "home [axis_list]")
        if args:
            log.debug("home %s: homing of single axes is simulated as homing all", args)
        if not self.arm.power:
            return Outcome(["Seeking axis 1...Failed.", "home: Arm power is OFF"])  # [inferred]
        duration = self.arm.home()
        lines = [
            f"Seeking axis {axis}...OK; Homing axis {axis}...Ok, seek distance of {1500 + 10 * axis}."
            for axis in range(1, JOINTS + 1)
        ]
        return Outcome(motion_s=duration, is_motion=True, waits=True, after=lines)

    def _ready(self, args: list[str]) -> Outcome:
        _no_args(args, "ready")
        return Outcome(motion_s=self.arm.move_to(self.arm.params.ready_pose_deg, "ready"), is_motion=True)

    def _axes(self, args: list[str], name: str) -> set[int]:
        if not args:
            return set(range(1, JOINTS + 1))
        for a in args:
            if not re.fullmatch(r"\d+", a) or not 1 <= int(a) <= JOINTS:
                raise _UsageError(f"{name}: illegal axis number '{a}'", f"{name} [axis_list]")  # [A]
        return {int(a) for a in args}

    def _limp(self, args: list[str]) -> Outcome:
        axes = self._axes(args, "limp")
        self.arm.stop()
        self.arm.limp |= axes
        return Outcome()

    def _nolimp(self, args: list[str]) -> Outcome:
        self.arm.limp -= self._axes(args, "nolimp")
        return Outcome()

    def _calrdy(self, args: list[str]) -> Outcome:
        _no_args(args, "calrdy")
        self.arm.calibrate_at_ready()
        return Outcome()

    def _armpower(self, args: list[str]) -> Outcome:
        if len(args) != 1 or args[0] not in {"on", "off"}:
            raise _UsageError("armpower: invalid command line arguments.", "armpower on|off")  # [A]
        self.arm.set_power(args[0] == "on")
        return Outcome()

    def _finish(self, args: list[str]) -> Outcome:
        _no_args(args, "finish")
        return Outcome(motion_s=self.arm.remaining_s())


class _UsageError(Exception):
    """Wrong arguments: the program prints a message, then ``Usage: ...`` [F]."""

    def __init__(self, message: str, usage: str) -> None:
        super().__init__(message)
        self.message = message
        self.usage = usage


def _no_args(args: list[str], name: str) -> None:
    if args:
        raise _UsageError(f"{name}: invalid command line arguments.", name)
