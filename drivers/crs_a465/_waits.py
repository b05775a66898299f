"""Waiting for the arm: a motion command sent and checked, then polled until the arm has arrived.

The second layer of :class:`drivers.crs_a465.CrsA465` (see ``DIALECT.md`` for what the controller does
and ``_motion`` for the arrival rules): ``joint`` and ``ready`` give the prompt back while the arm still
moves [F], so the driver polls: after ``joint``, ``w0`` alone while the arm moves, then armstat and
``w2``; after ``ready`` and ``home``, ``w0``/``w2`` pairs and armstat. A stop that latches while it waits
ends the wait at once with the position re-read.
"""

from __future__ import annotations

import logging
import re
from collections.abc import Sequence

from drivers.crs_a465 import _commands as cmd
from drivers.crs_a465._commands import Request
from drivers.crs_a465._errors import (
    HALT_NOTICE,
    POINT_OF_CONTROL,
    ArrivalError,
    find_error,
    unexpected,
)
from drivers.crs_a465._motion import (
    ArrivalTracker,
    deadline_s,
    expected_duration_s,
    worst_axis,
)
from drivers.crs_a465._replies import (
    PositionReport,
    check_printable,
)
from drivers.crs_a465._shell_link import Arrival, _fmt, _ShellLink
from station.devices import (
    DeviceError,
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionStoppedError,
    RobotPosition,
    StopLatchedError,
)
from station.local_ack import ACKNOWLEDGE_HINT

log = logging.getLogger(__name__)

SHOWN_EXACTLY_DEG = 0.0005 + 1e-9
"""A ``w0`` within this of a target shows the target itself (reported to 3 decimals)."""

_HOME_PROGRESS = re.compile(r"^(?:Seeking|Homing) axis \d+\.\.\..*$")
"""``home``'s per-axis lines (``Seeking axis 1...OK; Homing axis 1...Ok, seek distance of 1520.``) [F]."""


class _Waits(_ShellLink):
    """The motion command and the waits for its arrival."""

    def _motion_deadline(self, start: Sequence[float], end: Sequence[float]) -> tuple[float, float]:
        speed = self._speed_pct if self._speed_pct is not None else 1.0  # unknown: the slowest
        expected = expected_duration_s(start, end, speed, self.motion)
        return expected, deadline_s(expected, self.motion)

    def motion_deadline_s(self, start_deg: Sequence[float], target_deg: Sequence[float]) -> float:
        """How long a move from ``start_deg`` to ``target_deg`` may take at the current speed setting."""
        return self._motion_deadline(start_deg, target_deg)[1]

    def _command_motion(self, request: Request, timeout_s: float) -> None:
        """Send a motion command and check what it printed; a garbled or lost reply may hide a motion."""
        text = request.text(self.shell)
        if self._stopped.is_set():  # latched since the method began: send no motion after the halt key
            raise self._halted(f"{text} (not sent)")
        try:
            lines = self._run(request, timeout_s=timeout_s, watch=True)
            if self._stopped.is_set():
                raise self._halted(text)
            check_printable(text, lines)
        except (DeviceProtocolError, DeviceTimeoutError) as exc:
            if self._stopped.is_set():
                raise self._halted(text) from exc
            raise self._may_have_moved(exc, text) from exc
        rest: list[str] = []
        for line in lines:
            t = line.strip()
            if not t or POINT_OF_CONTROL.match(t) or (request is cmd.HOME and _HOME_PROGRESS.match(t)):
                continue
            if HALT_NOTICE.search(t):
                self._latch_now(f"the controller halted the robot during {text!r} (^Z detected)")
                raise self._halted(text)
            rest.append(t)
        if rest:  # never success on output the driver does not know
            error = find_error(rest, text) or unexpected(text, rest)
            self._last_error = error.controller_text
            raise error

    def _may_have_moved(self, exc: DeviceError, what: str) -> DeviceError:
        """A garbled or lost reply to a motion command: re-read the position, say the arm may have moved."""
        self._dirty = True
        try:
            self._resync()
            pos = self._where()
            self.last_position = pos
            where = (
                f"it is now commanded at {_fmt(pos.commanded_joints_deg)}, attained {_fmt(pos.joints_deg)}"
            )
        except DeviceError as again:
            where = f"its position could not be re-read ({again})"
        return type(exc)(f"{exc}. The arm may have moved after {what!r}: {where}; check it before going on")

    def _halted(self, what: str) -> MotionStoppedError:
        """The stop latched during a motion: resynchronise, re-read the position, say where the arm is."""
        self._dirty = True
        try:
            self._resync()
            pos = self._where()
            self.last_position = pos
            where = f"at {_fmt(pos.joints_deg)} (commanded {_fmt(pos.commanded_joints_deg)})"
        except DeviceError as exc:
            where = f"at an unknown position ({exc})"
        return StopLatchedError(
            f"{what} was stopped; the arm is {where}. The stop is latched: {ACKNOWLEDGE_HINT}",
            reason=self.latch.reason or "",
        )

    def _poll_failed(self, what: str, exc: DeviceError) -> DeviceError:
        if self._stopped.is_set():
            return self._halted(what)
        return self._may_have_moved(exc, what)

    def _sleep_watching(self, seconds: float, what: str) -> None:
        """Sleep ``seconds`` in steps of at most ``poll_interval_s``, raising at once if the stop latches."""
        until = self._clock() + seconds
        step = max(self.motion.poll_interval_s, 0.005)
        while (left := until - self._clock()) > 0.0:
            if self._stopped.is_set():
                raise self._halted(what)
            self._sleep(min(step, left))

    def _wait_target(
        self, what: str, target: tuple[float, ...], expected_s: float, limit_s: float, t0: float
    ) -> tuple[PositionReport, PositionReport]:
        """Wait until the arm has arrived at ``target``; return the ``w0`` and ``w2`` that prove it.

        While the arm moves only ``w0`` is polled (the cheapest reply that can show the end of the
        motion). Once ``w0`` equals the target, each poll reads armstat (where the shell has it), then
        ``w2``: the arm has arrived when that ``w2`` is within ``arrival_tolerance_deg`` of the target
        and either armstat, read just before it, shows every axis done, or it is within one encoder count
        of the previous poll's ``w2`` (both read after ``w0`` reached the target).
        """
        settings = self.motion
        expected_end = self._clock() + expected_s  # the prompt is back: the controller has the motion
        tracker = ArrivalTracker(target, settings, started_s=self._clock())
        w0: PositionReport | None = None
        w2: PositionReport | None = None
        w0_reply_s = 0.0  # how long the last w0 took to come back (the line's and controller's time)
        while True:
            if self._stopped.is_set():
                raise self._halted(what)
            done = False
            fresh_w0 = w0 is None or not tracker.at_target(w0.joints_deg)
            try:
                if fresh_w0:
                    asked = self._clock()
                    if asked < expected_end < asked + w0_reply_s:
                        # this poll would still be on the line when the motion is expected to end: poll
                        # at the end instead (a slow line then reads w0 once the arm is there)
                        self._sleep_watching(expected_end - asked, what)
                        asked = self._clock()
                    w0 = self._position(cmd.W0, motion_poll=True)
                    w0_reply_s = self._clock() - asked
                assert w0 is not None
                at_target = tracker.at_target(w0.joints_deg)
                if at_target:
                    if self.shell.has_armstat:
                        done = self._armstat(motion_poll=True).moving is False
                    w2 = self._position(cmd.W2, motion_poll=True)
            except (DeviceProtocolError, DeviceTimeoutError) as exc:
                raise self._poll_failed(what, exc) from exc
            if self._stopped.is_set():
                raise self._halted(what)
            now = self._clock()
            if fresh_w0:
                tracker.see_commanded(now, w0.joints_deg)
            if at_target and w2 is not None:
                still = tracker.see_actual(now, w2.pulses)
                if (done or still) and not tracker.gross(w2.joints_deg):
                    if abs(worst_axis(w0.joints_deg, target)[1]) > SHOWN_EXACTLY_DEG:
                        # that w0 was read while the set-point was still closing in on the target
                        # (within the resolution, not there): the next relative move starts from the
                        # commanded position, so read the one the motion ended at
                        w0 = self._position(cmd.W0, motion_poll=True)
                    self._fresh = (now, w0, w2)
                    return w0, w2
            if tracker.stalled(now):
                if at_target and w2 is not None:
                    self._arrived(what, target, w0, w2)  # at rest away from the target: says how far
                axis, diff = worst_axis(w0.joints_deg, target)
                raise ArrivalError(
                    f"{what}: the arm stopped short: joint {axis} is commanded at"
                    f" {w0.joints_deg[axis - 1]:.3f} deg, {diff:+.3f} deg from the target, and nothing has"
                    f" moved for {self.motion.stall_timeout_s:g} s; read the position (where) before going on"
                )
            if now - t0 > limit_s:
                attained = "not read" if w2 is None else _fmt(w2.joints_deg)
                raise DeviceTimeoutError(
                    f"{what}: the arm had not arrived after {limit_s:.3g} s (expected {expected_s:.3g} s x"
                    f" {self.motion.deadline_factor:g} + {self.motion.deadline_margin_s:g} s); commanded"
                    f" {_fmt(w0.joints_deg)}, attained {attained}; read the position (where)"
                )
            pause = self.motion.poll_interval_s
            if not at_target and now < expected_end < now + pause:
                pause = expected_end - now  # poll when the model says the motion ends
            elif not at_target and expected_end <= now < expected_end + 5.0 * pause:
                pause /= 10.0  # just past the model's end: look again soon (then back to the interval)
            self._sleep(pause)

    def _wait_still(
        self, what: str, expected_s: float, limit_s: float, t0: float
    ) -> tuple[PositionReport, PositionReport]:
        """``ready`` and ``home`` (whose end poses are assumptions, so no target): poll ``w0``/``w2``
        until both are still over two polls and armstat shows every axis done."""
        tracker = ArrivalTracker(None, self.motion, started_s=self._clock())
        while True:
            if self._stopped.is_set():
                raise self._halted(what)
            try:
                w0 = self._position(cmd.W0, motion_poll=True)
                w2 = self._position(cmd.W2, motion_poll=True)
            except (DeviceProtocolError, DeviceTimeoutError) as exc:
                raise self._poll_failed(what, exc) from exc
            if self._stopped.is_set():
                raise self._halted(what)
            now = self._clock()
            if tracker.update(now, w0.joints_deg, w2.pulses, w2.joints_deg) and self._all_done():
                return w0, w2
            if now - t0 > limit_s:
                raise DeviceTimeoutError(
                    f"{what}: the arm had not arrived after {limit_s:.3g} s (expected {expected_s:.3g} s x"
                    f" {self.motion.deadline_factor:g} + {self.motion.deadline_margin_s:g} s); commanded"
                    f" {_fmt(w0.joints_deg)}, attained {_fmt(w2.joints_deg)}; read the position (where)"
                )
            self._sleep(self.motion.poll_interval_s)

    def _all_done(self) -> bool:
        """armstat's ``done`` column says every axis has finished (True when armstat is not available)."""
        if not self.shell.has_armstat:
            return True
        return self._armstat().moving is not True

    def _arrived(self, what: str, target: tuple[float, ...], w0: PositionReport, w2: PositionReport) -> None:
        error = tuple(a - t for a, t in zip(w2.joints_deg, target, strict=True))
        self.last_arrival = Arrival(what, target, w0.joints_deg, w2.joints_deg, error)
        log.info("%s arrived: w2 - target = %s deg", what, _fmt(error))
        self.last_position = RobotPosition(w2.joints_deg, w0.joints_deg, w2.world_mm_deg)
        axis, diff = worst_axis(w2.joints_deg, target)
        if abs(diff) > self.motion.arrival_tolerance_deg:
            raise ArrivalError(
                f"{what}: the arm came to rest with joint {axis} at {w2.joints_deg[axis - 1]:.3f} deg,"
                f" {diff:+.3f} deg from the target (more than {self.motion.arrival_tolerance_deg:g} deg);"
                " check the arm for a collision or a servo fault"
            )

    def wait_settled(self, timeout_s: float | None = None) -> None:
        """Return when the arm is still (``w2`` unchanged within one count over two polls, armstat done).

        Motions of this driver already return on arrival; this waits for one started elsewhere.
        """
        limit = self.motion.deadline_margin_s if timeout_s is None else timeout_s
        with self._busy():
            t0 = self._clock()
            tracker = ArrivalTracker(None, self.motion, started_s=t0)
            while True:
                w0 = self._position(cmd.W0)
                w2 = self._position(cmd.W2)
                if tracker.update(self._clock(), w0.joints_deg, w2.pulses) and self._all_done():
                    return
                if self._clock() - t0 > limit:
                    raise DeviceTimeoutError(f"the arm did not settle within {limit:g} s")
                self._sleep(self.motion.poll_interval_s)
