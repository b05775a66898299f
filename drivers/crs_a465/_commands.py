"""The dialect: the two C500C shells, and each command the driver sends, defined once with its validator.

Command names and their meaning (``joint`` relative, ``w0`` commanded, ``w2`` actual, ``speed``,
``home``, ``ready``, ``armstat`` on both shells) are read from the firmware [F]; so is that ``joint``
and ``ready`` give the prompt back while the arm still moves (the driver waits for arrival itself).
The argument format of the application shell (comma-separated) and how to stop a motion (Ctrl-Z, which
the robot server's halt message names) are assumptions [A], each a setting of :class:`ShellProfile`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from drivers.crs_a465._errors import InvalidArgumentError
from station.devices import JOINT_COUNT

CommandKind = Literal["query", "action", "motion", "home"]


class ShellProfile(BaseModel):
    """One C500C command interpreter: its prompt, argument separator and what it can report."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["system", "application"] = "system"
    prompt: str = Field("$ ", min_length=1, description="what the controller prints when it is ready [C]")
    separator: str = Field(" ", min_length=1, description="between a command's arguments [C]")
    has_armstat: bool = Field(
        True, description="power, homing and per-axis state via armstat [F: both shells]"
    )
    stop_sequence: str = Field(
        "\x1a",
        min_length=1,
        description="[A] what halts a running motion: Ctrl-Z (the robot server's halt message names ^Z)",
    )
    joint_decimals: int = Field(3, ge=0, le=6, description="[F: w0 prints 3] decimals sent in joint moves")

    @classmethod
    def system(cls, **overrides: object) -> ShellProfile:
        """The system shell (``$ `` prompt, space-separated arguments): the default."""
        return cls.model_validate({"kind": "system", **overrides})

    @classmethod
    def application(cls, name: str = "ash", **overrides: object) -> ShellProfile:
        """The application shell ``ash`` (``NAME> `` prompt, comma-separated arguments, ``armstat``)."""
        if not name or any(c.isspace() for c in name):
            raise InvalidArgumentError(f"application name {name!r} must be one word (the prompt is 'NAME> ')")
        values: dict[str, object] = {
            "kind": "application",
            "prompt": f"{name}> ",
            "separator": ",",
        }
        return cls.model_validate({**values, **overrides})


@dataclass(frozen=True)
class Request:
    """One command line to send: its name, formatted arguments and how long it may take."""

    name: str
    args: tuple[str, ...] = ()
    kind: CommandKind = "query"

    def text(self, profile: ShellProfile) -> str:
        """The line as typed on the given shell (without the line ending)."""
        if not self.args:
            return self.name
        return f"{self.name} {profile.separator.join(self.args)}"


# ------------------------------------------------------------------ queries (no arguments)

W0 = Request("w0")
"""Commanded position table [C]."""
W2 = Request("w2")
"""Actual position table [C]."""
SPEED_QUERY = Request("speed")
"""``Current Speed: 50% of max.`` [C]."""
ARMSTAT = Request("armstat")
"""Arm type, power, homing and the per-axis locked/done/limped/homed table, both shells [F]."""

# ------------------------------------------------------------------ actions and motions

HOME = Request("home", kind="home")
"""Home all axes [C]."""
READY = Request("ready", kind="motion")
"""Go to the ready pose [C]."""


def set_speed(percent: float) -> Request:
    """``speed N``: the speed override in whole percent, 1-100 [A: integers only]."""
    if not isinstance(percent, int | float) or not math.isfinite(percent):
        raise InvalidArgumentError(f"speed must be a number of percent, got {percent!r}")
    if percent != int(percent) or not 1 <= percent <= 100:
        raise InvalidArgumentError(f"speed must be a whole percent from 1 to 100, got {percent!r}")
    return Request("speed", (str(int(percent)),), kind="action")  # [F] whole numbers 1-100


def check_axis(axis: int) -> int:
    """Validate a joint number (1-6)."""
    if isinstance(axis, bool) or not isinstance(axis, int) or not 1 <= axis <= JOINT_COUNT:
        raise InvalidArgumentError(f"axis must be a joint number from 1 to {JOINT_COUNT}, got {axis!r}")
    return axis


def joint(axis: int, delta_deg: float, *, profile: ShellProfile) -> Request:
    """``joint AXIS DEGREES``: move one joint relatively [C], the angle rounded to the profile's decimals."""
    check_axis(axis)
    if not isinstance(delta_deg, int | float) or not math.isfinite(delta_deg):
        raise InvalidArgumentError(
            f"joint {axis}: the angle must be a finite number of degrees, got {delta_deg!r}"
        )
    return Request("joint", (str(axis), f"{delta_deg:.{profile.joint_decimals}f}"), kind="motion")


def quantise(delta_deg: float, profile: ShellProfile) -> float:
    """The angle the controller will receive for ``delta_deg`` (rounded as :func:`joint` formats it)."""
    return float(f"{delta_deg:.{profile.joint_decimals}f}")


__all__ = [
    "ARMSTAT",
    "HOME",
    "READY",
    "SPEED_QUERY",
    "W0",
    "W2",
    "Request",
    "ShellProfile",
    "check_axis",
    "joint",
    "quantise",
    "set_speed",
]
