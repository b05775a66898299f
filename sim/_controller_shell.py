"""The twin's command interpreters: the C500C system shell (``$ ``) and the application shell (``NAME> ``).

Pure text in, text out: :meth:`Shell.execute` takes one typed line and returns the reply lines and how
long the arm will move. The pty server (``sim.controller``) adds echo, prompt, timing and faults.
Reply texts follow docs/crs-c500c-protocol.md; where the doc marks a format [A], the choice made here
is noted, so that the twin never claims more than is known.
"""

from __future__ import annotations

import logging
import math
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


def position_table(
    title: str, joints_deg: npt.NDArray[np.float64], pulses: list[int], world: tuple[float, ...]
) -> list[str]:
    """The ``w0``/``w2`` table: row labels and number formats [C], column spacing [A]."""
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
        if kind == "application":
            self._commands.update(
                {"armstat": self._armstat, "armpower": self._armpower, "finish": self._finish}
            )

    @property
    def prompt(self) -> str:
        return "$ " if self.kind == "system" else f"{self.app_name}> "

    def _error(self, program: str, text: str) -> Outcome:
        # System shell programs print 'PROGRAM: MESSAGE' [C]; the application shell 'error: '
        # [C; on the same line as the text: A].
        return Outcome([f"{program}: {text}" if self.kind == "system" else f"error: {text}"])

    def _unknown(self) -> Outcome:
        return Outcome(["Unrecognized command." if self.kind == "system" else "error: Unrecognized command."])

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
            return self._unknown()
        try:
            return handler(self._args(rest))
        except ArmError as exc:
            return self._error(name, exc.text)
        except _UsageError as exc:
            return self._error(name, f"usage: {exc}")

    # ---------------------------------------------------------------- reports

    def _table(self, title: str, joints: npt.NDArray[np.float64], pulses: list[int]) -> Outcome:
        world = world_row(self.arm.kinematics.flange(joints))
        return Outcome(position_table(title, joints, pulses, world))

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
            return Outcome([f"Current Speed: {self.arm.speed_pct}% of max."])
        if len(args) != 1:
            raise _UsageError("speed [percent]")
        try:
            value = float(args[0])
        except ValueError:
            raise ArmError("015 Illegal speed chosen") from None
        if not (math.isfinite(value) and value == int(value) and 1 <= value <= 100):
            raise ArmError("015 Illegal speed chosen")
        self.arm.speed_pct = int(value)
        return Outcome()  # [A] setting the speed prints nothing

    def _armstat(self, args: list[str]) -> Outcome:
        _no_args(args, "armstat")
        return Outcome(
            [
                "Robot arm is of type A465",
                f"Arm Power is {'ON' if self.arm.power else 'OFF'}",
                "Robot is calibrated and homed" if self.arm.homed else "Robot is not homed",  # negative: [A]
            ]
        )

    # ---------------------------------------------------------------- actions

    def _joint(self, args: list[str]) -> Outcome:
        if len(args) != 2:
            raise _UsageError("joint <axis> <degrees>" if self.kind == "system" else "joint <axis>,<degrees>")
        try:
            axis = int(args[0])
            degrees = float(args[1])
        except ValueError:
            raise _UsageError("joint <axis> <degrees>") from None
        if not 1 <= axis <= JOINTS or not math.isfinite(degrees):
            raise _UsageError("joint <axis> <degrees>")
        return Outcome(motion_s=self.arm.move_joint(axis, degrees), is_motion=True)

    def _home(self, args: list[str]) -> Outcome:
        if args:
            log.debug("home %s: homing of single axes is simulated as homing all", args)
        return Outcome(motion_s=self.arm.home(), is_motion=True)

    def _ready(self, args: list[str]) -> Outcome:
        _no_args(args, "ready")
        return Outcome(motion_s=self.arm.move_to(self.arm.params.ready_pose_deg, "ready"), is_motion=True)

    def _axes(self, args: list[str], usage: str) -> set[int]:
        if not args:
            return set(range(1, JOINTS + 1))
        try:
            axes = {int(a) for a in args}
        except ValueError:
            raise _UsageError(usage) from None
        if not all(1 <= a <= JOINTS for a in axes):
            raise _UsageError(usage)
        return axes

    def _limp(self, args: list[str]) -> Outcome:
        axes = self._axes(args, "limp [axes]")
        self.arm.stop()
        self.arm.limp |= axes
        return Outcome()

    def _nolimp(self, args: list[str]) -> Outcome:
        self.arm.limp -= self._axes(args, "nolimp [axes]")
        return Outcome()

    def _calrdy(self, args: list[str]) -> Outcome:
        _no_args(args, "calrdy")
        self.arm.calibrate_at_ready()
        return Outcome()

    def _armpower(self, args: list[str]) -> Outcome:
        if len(args) != 1 or args[0] not in {"on", "off"}:
            raise _UsageError("armpower on|off")
        self.arm.set_power(args[0] == "on")
        return Outcome()

    def _finish(self, args: list[str]) -> Outcome:
        _no_args(args, "finish")
        return Outcome(motion_s=self.arm.remaining_s())


class _UsageError(Exception):
    """Wrong arguments: the shell prints a usage line [A]."""


def _no_args(args: list[str], usage: str) -> None:
    if args:
        raise _UsageError(usage)
