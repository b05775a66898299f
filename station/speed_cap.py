"""The station's speed cap: the speed override (percent of the arm's maximum) no plan, jog or Align may
exceed, ``max_speed_pct`` in ``[robot] safety`` of the station configuration (default 50).

The robot driver refuses a higher ``set_speed`` before anything is sent (its ``check_speed`` does the
same with no I/O); a session's pre-flight checks its plan's speeds with :func:`check_plan_speeds`, so
that a plan asking for more (repeatability's default 80 under the default cap) is refused before
anything moves::

    from station.speed_cap import check_plan_speeds, speed_cap_of
    problems = check_plan_speeds({"speed_pct": params.speed_pct}, speed_cap_of(config.robot_safety()))
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from station.devices import MotionRejectedError

__all__ = [
    "DEFAULT_MAX_SPEED_PCT",
    "SPEED_CAP_SETTING",
    "SpeedCapError",
    "check_plan_speeds",
    "check_speed",
    "speed_cap_of",
]

DEFAULT_MAX_SPEED_PCT = 50.0
"""The cap when the configuration does not set one (issue 23)."""

SPEED_CAP_SETTING = "max_speed_pct in [robot] safety of the station configuration (station.toml)"
"""Where the cap is set: said in every refusal."""


class SpeedCapError(MotionRejectedError):
    """A speed above the station's cap was asked for; nothing was sent. ``requested`` and ``cap`` in %."""

    def __init__(self, message: str, *, requested: float, cap: float) -> None:
        super().__init__(message)
        self.requested = requested
        self.cap = cap


def check_speed(percent: float, cap_pct: float, *, what: str = "speed") -> None:
    """Raise :class:`SpeedCapError` when ``percent`` exceeds ``cap_pct`` (or is not a number)."""
    try:
        value = float(percent)
    except (TypeError, ValueError):
        raise SpeedCapError(
            f"{what} {percent!r} is not a number of percent", requested=math.nan, cap=cap_pct
        ) from None
    if not math.isfinite(value) or value > cap_pct + 1e-9:
        raise SpeedCapError(
            f"{what} {value:g} % refused: the station's speed cap is {cap_pct:g} % ({SPEED_CAP_SETTING});"
            f" ask for {cap_pct:g} % or less, or raise the cap there if the lab has approved it",
            requested=value,
            cap=cap_pct,
        )


def speed_cap_of(safety: Mapping[str, Any] | None) -> float:
    """The cap of a robot's safety settings (``[robot] safety``), else :data:`DEFAULT_MAX_SPEED_PCT`."""
    value = (safety or {}).get("max_speed_pct", DEFAULT_MAX_SPEED_PCT)
    cap = float(value)
    if not (math.isfinite(cap) and 1.0 <= cap <= 100.0):
        raise ValueError(f"max_speed_pct must be 1 to 100, got {value!r}")
    return cap


def check_plan_speeds(speeds: Mapping[str, float], cap_pct: float) -> list[str]:
    """Pre-flight: one problem (the refusal's text) per plan parameter whose speed exceeds the cap;
    ``speeds`` maps the parameter's name (``speed_pct``, ``align_speed_pct``) to its value."""
    problems = []
    for name, value in speeds.items():
        try:
            check_speed(value, cap_pct, what=f"the plan's {name}")
        except SpeedCapError as exc:
            problems.append(str(exc))
    return problems
