"""Motion that outlives the prompt: expected durations, deadlines and the arrival test.

``joint`` and ``ready`` give the prompt back at once while the arm still moves [F], so the driver
decides arrival itself from what it polls. After ``joint`` the arm has arrived when the commanded
position (``w0``) equals the target within the controller's resolution, and then a ``w2`` (actual
position) is within ``arrival_tolerance_deg`` of the target and either armstat, read just before that
``w2``, shows every axis done, or that ``w2`` is within one encoder count of the previous poll's (read
at least ``poll_interval_s`` earlier, after ``w0`` reached the target). A still arm further away has not
started yet, or has stopped short: the stall timeout decides. While the arm moves only ``w0`` is polled
(each poll of a real console costs about 0.1 s of line time: ``w0``, ``w2`` and armstat are 570-650
bytes at 57600 baud), and a poll that would still be on the line when the motion is expected to end
waits for that end instead. After ``ready`` and ``home`` (end poses assumed) ``w0`` and ``w2`` must both
be still over two polls and armstat show every axis done.

The deadline of a move is its expected duration (trapezoidal profile, configurable joint speeds and
accelerations, at the current speed setting) times ``deadline_factor`` plus ``deadline_margin_s``; a
move fails earlier only when the position has not changed for ``stall_timeout_s`` while the target is
not reached. The speeds and accelerations are public figures of another model of the arm [A]; the
deadline's factor leaves room for them to be wrong, and a wrong figure only delays the poll that finds
the arm arrived.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field

from station.devices import JOINT_COUNT, Joints6


class MotionSettings(BaseModel):
    """How the driver waits for a motion: timing model, deadline, stall, polling and tolerances."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    max_speed_deg_s: Joints6 = Field(
        (180.0, 180.0, 180.0, 172.0, 172.0, 172.0), description="[A] joint speeds at 100 % speed"
    )
    accel_deg_s2: Joints6 = Field(
        (720.0, 720.0, 720.0, 1430.0, 1430.0, 1430.0), description="[A] joint accelerations (not scaled)"
    )
    deadline_factor: float = Field(3.0, ge=1.0, description="deadline = expected duration x this + margin")
    deadline_margin_s: float = Field(5.0, ge=0.0)
    stall_timeout_s: float = Field(3.0, gt=0.0, description="no change this long, target not reached: fail")
    poll_interval_s: float = Field(
        0.02, ge=0.0, description="pause between two polls; two w2 compared for stillness are this far apart"
    )
    reuse_s: float = Field(
        0.05,
        ge=0.0,
        description="a position read after arrival, with nothing sent since, stands for where() and for"
        " the next move's start this long (0: always read again)",
    )
    resolution_deg: float = Field(0.002, gt=0.0, description="w0 equals the target within this (3 decimals)")
    arrival_tolerance_deg: float = Field(
        0.5, gt=0.0, description="|w2 - target| beyond this after arrival is an error (gross difference)"
    )
    pose_tolerance_deg: float = Field(
        0.01, gt=0.0, description="ready/home: w0 further than this from the configured pose warns"
    )
    home_pose_deg: Joints6 | None = Field((0.0,) * 6, description="[A] where home ends (None: not compared)")
    point_of_control_wait_s: float = Field(
        600.0, ge=0.0, description="extra time granted while the pendant holds the point of control"
    )


def trapezoid_time(distance: float, speed: float, accel: float) -> float:
    """Duration (s) of a rest-to-rest trapezoidal (or triangular) move."""
    if distance <= 0.0:
        return 0.0
    if distance >= speed * speed / accel:
        return distance / speed + speed / accel
    return 2.0 * math.sqrt(distance / accel)


def expected_duration_s(
    start_deg: Sequence[float], end_deg: Sequence[float], speed_pct: float, settings: MotionSettings
) -> float:
    """Expected duration of a synchronised joint move at ``speed_pct`` (the slowest joint's)."""
    scale = max(1.0, min(100.0, speed_pct)) / 100.0
    return max(
        trapezoid_time(abs(b - a), v * scale, acc)
        for a, b, v, acc in zip(
            start_deg, end_deg, settings.max_speed_deg_s, settings.accel_deg_s2, strict=True
        )
    )


def deadline_s(expected_s: float, settings: MotionSettings) -> float:
    """The time a move may take: expected duration x factor + margin."""
    return expected_s * settings.deadline_factor + settings.deadline_margin_s


@dataclass
class ArrivalTracker:
    """Decides arrival, stall and gross error from successive polls of ``w0`` and ``w2`` (no I/O).

    ``target`` ``None``: any still commanded position is accepted (``ready`` and ``home``, whose end
    pose is an assumption); the caller compares it with the configured pose.
    """

    target: tuple[float, ...] | None
    settings: MotionSettings
    started_s: float
    last_w2_pulses: tuple[int, ...] | None = None
    last_w0: tuple[float, ...] | None = None
    last_change_s: float = 0.0
    polls: int = 0

    def __post_init__(self) -> None:
        self.last_change_s = self.started_s

    def at_target(self, commanded: Sequence[float]) -> bool:
        if self.target is None:
            return False
        return (
            max(abs(c - t) for c, t in zip(commanded, self.target, strict=True))
            <= self.settings.resolution_deg
        )

    def update(
        self,
        now_s: float,
        commanded: Sequence[float],
        actual_pulses: Sequence[int],
        actual_deg: Sequence[float] | None = None,
    ) -> bool:
        """Record one poll (``w0``'s joints, ``w2``'s pulses and joints); True when the arm has arrived."""
        self.polls += 1
        w0 = tuple(commanded)
        pulses = tuple(actual_pulses)
        still = self.last_w2_pulses is not None and all(
            abs(a - b) <= 1 for a, b in zip(pulses, self.last_w2_pulses, strict=True)
        )
        w0_still = self.last_w0 is not None and w0 == self.last_w0
        if not (still and w0_still):
            self.last_change_s = now_s
        self.last_w2_pulses, self.last_w0 = pulses, w0
        if not still:
            return False
        if self.target is None:
            return w0_still
        # w2 still but grossly away from the target: the motion may not have started yet (or the arm
        # stopped short); keep polling, the stall timeout decides
        return self.at_target(w0) and not self.gross(actual_deg)

    def see_commanded(self, now_s: float, commanded: Sequence[float]) -> bool:
        """Record a ``w0`` polled alone while the arm moves; True when it equals the target."""
        self.polls += 1
        w0 = tuple(commanded)
        if w0 != self.last_w0:
            self.last_change_s = now_s
        self.last_w0 = w0
        return self.at_target(w0)

    def see_actual(self, now_s: float, actual_pulses: Sequence[int]) -> bool:
        """Record a ``w2``; True when it is within one encoder count of the previous ``w2`` recorded."""
        self.polls += 1
        pulses = tuple(actual_pulses)
        still = self.last_w2_pulses is not None and all(
            abs(a - b) <= 1 for a, b in zip(pulses, self.last_w2_pulses, strict=True)
        )
        if not still:
            self.last_change_s = now_s
        self.last_w2_pulses = pulses
        return still

    def gross(self, actual_deg: Sequence[float] | None) -> bool:
        """Whether the actual joints are further than ``arrival_tolerance_deg`` from the target."""
        if self.target is None or actual_deg is None:
            return False
        tolerance = self.settings.arrival_tolerance_deg
        return any(abs(a - t) > tolerance for a, t in zip(actual_deg, self.target, strict=True))

    def stalled(self, now_s: float) -> bool:
        """Nothing changed for ``stall_timeout_s`` while the target is not reached."""
        return now_s - self.last_change_s >= self.settings.stall_timeout_s


def worst_axis(a: Sequence[float], b: Sequence[float]) -> tuple[int, float]:
    """(axis 1-6, a - b) of the largest difference."""
    diffs = [x - y for x, y in zip(a, b, strict=True)]
    i = max(range(JOINT_COUNT), key=lambda k: abs(diffs[k]))
    return i + 1, diffs[i]


__all__ = [
    "ArrivalTracker",
    "MotionSettings",
    "deadline_s",
    "expected_duration_s",
    "trapezoid_time",
    "worst_axis",
]
