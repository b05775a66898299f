"""The CRS A465 on a C500C controller, as a :class:`station.devices.Robot`.

One command at a time: consume the echo, wait for the prompt, look for a controller error, parse the
reply (``_replies``). Motions are checked by the :class:`MotionGuard` before anything is written; an
absolute move is composed from ``w0`` and single-joint relative ``joint`` moves (the system shell has no
absolute multi-joint command [F]). ``joint`` and ``ready`` give the prompt back while the arm still
moves [F], so after each the driver polls until the arm has arrived (``_motion``): after ``joint``,
``w0`` alone while the arm moves, then armstat and ``w2``; after ``ready`` and ``home``, ``w0``/``w2``
pairs and armstat. The readings that proved an arrival stand for :meth:`CrsA465.where` and for the next
move's start while nothing has been sent since and for at most ``MotionSettings.reuse_s``.

The stop is best effort: ``stop()`` latches (every motion raises :class:`MotionStoppedError` until
:meth:`CrsA465.clear_stop`), sends the halt key (Ctrl-Z by default), resynchronises the line and
re-reads the position. On a real arm the E-stop is the stop.
"""

from __future__ import annotations

import logging
import re
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType

import serial

from drivers.crs_a465 import _commands as cmd
from drivers.crs_a465._commands import Request, ShellProfile
from drivers.crs_a465._errors import (
    HALT_NOTICE,
    POINT_OF_CONTROL,
    ArrivalError,
    CrsControllerError,
    InvalidArgumentError,
    error_of_line,
    find_error,
    rejected,
    unexpected,
)
from drivers.crs_a465._link import LinkSettings, SerialTransport
from drivers.crs_a465._motion import (
    ArrivalTracker,
    MotionSettings,
    deadline_s,
    expected_duration_s,
    worst_axis,
)
from drivers.crs_a465._replies import (
    ArmStat,
    PositionKind,
    PositionReport,
    check_printable,
    check_silent,
    parse_armstat,
    parse_position,
    parse_speed,
    raise_for_error,
)
from drivers.crs_a465._safety import MotionGuard, PlannedMove, SafetyLimits
from station.devices import (
    JOINT_COUNT,
    DeviceConnectionError,
    DeviceError,
    DeviceIdentity,
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionStoppedError,
    RobotPosition,
    RobotStatus,
)
from station.kinematics import Kinematics

log = logging.getLogger(__name__)

SHOWN_EXACTLY_DEG = 0.0005 + 1e-9
"""A ``w0`` within this of a target shows the target itself (reported to 3 decimals)."""

_HOME_PROGRESS = re.compile(r"^(?:Seeking|Homing) axis \d+\.\.\..*$")
"""``home``'s per-axis lines (``Seeking axis 1...OK; Homing axis 1...Ok, seek distance of 1520.``) [F]."""
_SERVER_LINE = re.compile(r"^/sbin/\S+: ")
"""A line the robot server prints unprompted [inferred]."""


def _fmt(q: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in q) + ")"


@dataclass(frozen=True)
class Arrival:
    """Where a motion ended: its target, ``w0`` and ``w2`` after arrival, and ``w2 - target`` (deg)."""

    what: str
    target_deg: tuple[float, ...] | None
    commanded_deg: tuple[float, ...]
    actual_deg: tuple[float, ...]
    error_deg: tuple[float, ...] | None


class CrsA465:
    """A CRS A465 arm behind a C500C controller's serial console (system or application shell).

    Parameters
    ----------
    port
        A port name (``/dev/ttyS0``), a pyserial URL (``loop://``, ``socket://host:port``, a pty path)
        or an already built ``serial.SerialBase``. Names are opened exclusively.
    link
        Serial parameters, line ending, echo and timeouts (:class:`LinkSettings`).
    shell
        The command interpreter (:meth:`ShellProfile.system` by default).
    safety
        Joint limits, maximum step and keep-out checked before any motion (:class:`SafetyLimits`).
    kinematics
        The arm's kinematics for the keep-out (nominal A465 by default).
    motion
        Timing model, deadlines, stall timeout, polling and tolerances (:class:`MotionSettings`).
    on_notice
        Called with the controller's text when it announces a wait (the teach pendant holds the point of
        control): the motion goes on once the operator presses PAUSE/CONTINUE. Default: a log warning.
    clock, sleep
        Monotonic clock and sleep (seconds) for deadlines and polling; injected by tests.
    """

    def __init__(
        self,
        port: str | serial.SerialBase,
        *,
        link: LinkSettings | None = None,
        shell: ShellProfile | None = None,
        safety: SafetyLimits | None = None,
        kinematics: Kinematics | None = None,
        motion: MotionSettings | None = None,
        on_notice: Callable[[str], None] | None = None,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.link = link or LinkSettings()
        self.shell = shell or ShellProfile.system()
        self.guard = MotionGuard(safety, kinematics)
        self.motion = motion or MotionSettings()
        self._on_notice = on_notice
        self._clock = clock
        self._sleep = sleep
        self._transport = SerialTransport(port, self.link, clock=clock)
        self._lock = threading.RLock()
        self._owner: int | None = None  # the thread running a command, for stop()
        self._stopped = threading.Event()  # the latch
        self._dirty = True
        self._last_error: str | None = None
        self._speed_pct: float | None = None
        self._commanded: tuple[float, ...] | None = None
        self._arm_type: str | None = None
        self._linked = False  # connect() succeeded and close() has not been called since
        self.last_status: RobotStatus | None = None
        self.last_position: RobotPosition | None = None
        self.last_arrival: Arrival | None = None
        self.last_notice: str | None = None
        # w0 and w2 read at an arrival, with the time the w2 reply was complete: where() and the next
        # move's start reuse them for MotionSettings.reuse_s if nothing has been sent since
        self._fresh: tuple[float, PositionReport, PositionReport] | None = None

    # ---------------------------------------------------------------- link

    @property
    def port_name(self) -> str:
        return str(self._transport.name)

    @property
    def is_connected(self) -> bool:
        return self._transport.is_open

    @property
    def stopped(self) -> bool:
        """Whether ``stop()`` is latched (motions refused until :meth:`clear_stop`)."""
        return self._stopped.is_set()

    def connect(self) -> None:
        """Open (or re-open) the link, find the prompt and re-read the arm state (a stop stays latched)."""
        with self._lock:
            self._transport.close()
            self._transport.open()
            self._dirty = True
            try:
                self._resync()
                self.last_status = self._status()
                self.last_position = self._where()
            except BaseException:
                self._transport.close()
                raise
            self._linked = True
            log.info(
                "connected to %s: speed %s%%, commanded %s",
                self.port_name,
                self.last_status.speed_pct,
                self.last_position.commanded_joints_deg,
            )

    def close(self) -> None:
        """Close the link; safe to call twice."""
        with self._lock:
            self._linked = False
            self._transport.close()

    def __enter__(self) -> CrsA465:
        if not self.is_connected:
            self.connect()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def identity(self) -> DeviceIdentity:
        """The arm type armstat reports (read at connect), the port; no serial or firmware report is known."""
        return DeviceIdentity(model=self._arm_type, serial=None, port=self.port_name, firmware=None)

    def _resync(self) -> None:
        """Drop stale input, then type empty lines until the controller answers one with a bare prompt."""
        self._fresh = None
        self._transport.drain()
        quick = max(self.link.resync_quiet_s, 2 * self.link.poll_s)
        for _ in range(3):
            self._transport.write_line("")
            wait = self.link.reply_timeout_s
            while True:
                try:
                    lines = self._transport.read_until_prompt(self.shell.prompt, wait, what="(empty line)")
                except DeviceTimeoutError:
                    if wait == self.link.reply_timeout_s:
                        raise
                    break  # no further prompt is coming: type another empty line
                if not self.link.echo or (lines and lines[-1].strip() == ""):
                    self._note_unsolicited(lines[:-1])
                    self._dirty = False
                    return
                log.debug("resync: skipped %r", lines)
                self._note_unsolicited(lines)
                wait = quick
        raise DeviceProtocolError(
            f"{self.port_name!r} answered three empty lines with something other than a bare"
            f" {self.shell.prompt!r} prompt; check the shell setting and that no other program uses the port"
        )

    def _note_unsolicited(self, lines: Sequence[str]) -> None:
        for line in lines:
            error = error_of_line(line)
            if error is not None:
                self._last_error = error.controller_text

    # ---------------------------------------------------------------- one exchange

    def _run(
        self,
        request: Request,
        *,
        timeout_s: float | None = None,
        motion_poll: bool = False,
        watch: bool = False,
    ) -> list[str]:
        """Send one command; return its reply lines (echo removed) or raise the controller's error.

        ``motion_poll``: a poll while a motion runs; robot-server lines are errors of that motion.
        ``watch``: a motion command; the point-of-control notice extends the deadline, a stop shortens it.
        """
        text = request.text(self.shell)
        self._fresh = None  # whatever is sent, a reading taken before it no longer stands for now
        if self._dirty:
            self._resync()
        self._transport.write_line(text)
        self._dirty = True  # until the prompt has come, the link is out of step
        lines = self._transport.read_until_prompt(
            self.shell.prompt,
            self.link.reply_timeout_s if timeout_s is None else timeout_s,
            what=text,
            on_line=self._watch_line if watch else None,
            interrupted=self._stopped.is_set if watch else None,
        )
        self._dirty = False
        if self.link.echo:
            lines = self._strip_echo(text, lines, motion_poll=motion_poll)
        if motion_poll:
            server = [line for line in lines if _SERVER_LINE.match(line.strip())]
            if server:
                self._server_lines(server, text)
                lines = [line for line in lines if line not in server]
        try:
            raise_for_error(
                text, [x for x in lines if not POINT_OF_CONTROL.match(x.strip())] if watch else lines
            )
        except CrsControllerError as exc:
            self._last_error = exc.controller_text
            raise
        return lines

    def _watch_line(self, line: str) -> float:
        if POINT_OF_CONTROL.match(line.strip()):
            self.last_notice = line.strip()
            if self._on_notice is not None:
                self._on_notice(line.strip())
            else:
                log.warning("%s: %s (waiting for the button)", self.port_name, line.strip())
            return self.motion.point_of_control_wait_s
        return 0.0

    def _strip_echo(self, text: str, lines: list[str], *, motion_poll: bool = False) -> list[str]:
        """Remove the echo; lines before it are output nobody asked for (logged, errors remembered)."""
        for i, line in enumerate(lines):
            if line.strip() == text:
                if i:
                    if motion_poll:
                        self._server_lines(lines[:i], text)
                    else:
                        self._unsolicited(lines[:i])
                return lines[i + 1 :]
        check_printable(text, lines)
        raise DeviceProtocolError(
            f"no echo of {text!r} in the reply {lines!r}; another program may be using the port"
        )

    def _unsolicited(self, lines: list[str]) -> None:
        log.warning("%s printed %r unasked", self.port_name, lines)
        error = find_error(lines)
        if error is not None:
            self._last_error = error.controller_text

    def _server_lines(self, lines: list[str], during: str) -> None:
        """Lines printed unprompted while a motion runs: a halt or an error of that motion."""
        texts = [line.strip() for line in lines if line.strip()]
        if not texts:
            return
        if any(HALT_NOTICE.search(t) for t in texts):
            self._stopped.set()  # halted at the controller: latch like stop()
            self._dirty = True
            return
        error = find_error(texts, during)
        if error is None:
            error = unexpected(during, texts)
        self._last_error = error.controller_text
        raise error

    def _position(self, request: Request, *, motion_poll: bool = False) -> PositionReport:
        kind: PositionKind = "commanded" if request is cmd.W0 else "actual"
        report = parse_position(
            self._run(request, motion_poll=motion_poll), expect=kind, command=request.name
        )
        if kind == "commanded":
            self._commanded = report.joints_deg
        return report

    def _read_commanded(self) -> tuple[float, ...]:
        return self._position(cmd.W0).joints_deg

    def _fresh_reading(self) -> tuple[PositionReport, PositionReport] | None:
        """``(w0, w2)`` read at the last arrival, if nothing was sent since and it is younger than
        ``MotionSettings.reuse_s``: the arm was proven at rest then, and only a command moves it."""
        fresh = self._fresh
        if fresh is None or self._stopped.is_set() or not self._linked or not self._transport.is_open:
            return None
        at, w0, w2 = fresh
        if self._clock() - at > self.motion.reuse_s:
            self._fresh = None
            return None
        return w0, w2

    def _start_commanded(self) -> tuple[float, ...]:
        """The commanded position a relative move starts from: the arrival's ``w0`` while fresh, else read."""
        fresh = self._fresh_reading()
        return fresh[0].joints_deg if fresh is not None else self._read_commanded()

    # ---------------------------------------------------------------- reports

    def _armstat(self, *, motion_poll: bool = False) -> ArmStat:
        stat = parse_armstat(self._run(cmd.ARMSTAT, motion_poll=motion_poll))
        if stat.arm_type is not None:
            self._arm_type = stat.arm_type
        return stat

    def _status(self) -> RobotStatus:
        speed = parse_speed(self._run(cmd.SPEED_QUERY))
        self._speed_pct = speed
        stat = self._armstat() if self.shell.has_armstat else None
        return RobotStatus(
            power=None if stat is None else stat.power,
            homed=None if stat is None else stat.homed,
            moving=None if stat is None else stat.moving,
            speed_pct=speed,
            last_error=self._last_error,
            calibrated=None if stat is None else stat.calibrated,
            arm_type=self._arm_type,
        )

    def status(self) -> RobotStatus:
        """Speed, and from armstat power, calibration, homing, motion (its ``done`` column), arm type."""
        with self._busy():
            self.last_status = self._status()
            return self.last_status

    def _where(self) -> RobotPosition:
        actual = self._position(cmd.W2)
        commanded = self._position(cmd.W0)
        return RobotPosition(
            joints_deg=actual.joints_deg,
            commanded_joints_deg=commanded.joints_deg,
            world_mm_deg=actual.world_mm_deg,
        )

    def where(self) -> RobotPosition:
        """Attained (``w2``) and commanded (``w0``) joints, and the WORLD row of the attained position.

        Right after a motion (within ``MotionSettings.reuse_s`` of the arrival, nothing sent since) the
        readings that proved the arrival are returned instead of reading them again.
        """
        with self._busy():
            fresh = self._fresh_reading()
            if fresh is not None:
                w0, w2 = fresh
                self.last_position = RobotPosition(w2.joints_deg, w0.joints_deg, w2.world_mm_deg)
                return self.last_position
            self.last_position = self._where()
            return self.last_position

    # ---------------------------------------------------------------- host checks

    def _target(self, target_deg: Sequence[float]) -> list[float]:
        try:
            target = [float(v) for v in target_deg]
        except (TypeError, ValueError) as exc:
            raise rejected(f"target must be {JOINT_COUNT} numbers of degrees: {exc}") from exc
        if len(target) != JOINT_COUNT:
            raise rejected(f"target must be {JOINT_COUNT} joint angles, got {len(target)}")
        return target

    def _plan(self, target: Sequence[float], start: Sequence[float]) -> PlannedMove:
        self.guard.check_limits(target)
        steps = [(i + 1, cmd.quantise(target[i] - start[i], self.shell)) for i in range(JOINT_COUNT)]
        return self.guard.plan_single_joint_moves(start, steps)

    def check_move(self, target_deg: Sequence[float], *, start_deg: Sequence[float] | None = None) -> None:
        """Raise what ``move_joints(target_deg)`` from ``start_deg`` would raise on the host; no I/O.

        ``start_deg`` ``None``: the last commanded position this driver knows (read by ``connect``, kept
        up to date by every move). Raises :class:`MotionRejectedError` (limits, step, keep-out).
        """
        target = self._target(target_deg)
        if start_deg is None:
            if self._commanded is None:
                raise DeviceConnectionError(
                    "no commanded position is known yet: connect() first, or pass start_deg"
                )
            start = list(self._commanded)
        else:
            start = self._target(start_deg)
        self._plan(target, start)

    # ---------------------------------------------------------------- motions

    def _busy(self) -> _Busy:
        return _Busy(self)

    def _refuse_if_stopped(self, what: str) -> None:
        if self._stopped.is_set():
            raise MotionStoppedError(
                f"{what} refused: a stop is latched (stop() or a halt at the controller); read the"
                " position, then call clear_stop() to accept motions again"
            )

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
                self._stopped.set()
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
        return MotionStoppedError(
            f"{what} was stopped; the arm is {where}. The stop is latched: call clear_stop() before the"
            " next motion"
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

    def _joint_step(self, axis: int, delta: float, start: tuple[float, ...]) -> tuple[float, ...]:
        target = list(start)
        target[axis - 1] = round(start[axis - 1] + delta, self.shell.joint_decimals + 3)
        end = tuple(target)
        request = cmd.joint(axis, delta, profile=self.shell)
        expected, limit = self._motion_deadline(start, end)
        t0 = self._clock()
        self._command_motion(request, limit)
        what = request.text(self.shell)
        w0, w2 = self._wait_target(what, end, expected, limit, t0)
        self._arrived(what, end, w0, w2)
        return w0.joints_deg

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

    def _run_plan(self, plan: PlannedMove) -> tuple[float, ...]:
        position = plan.start_deg
        for axis, delta in plan.steps:
            position = self._joint_step(axis, delta, position)
        return position

    def move_joint(self, axis: int, delta_deg: float) -> None:
        """Move one joint (1-6) by ``delta_deg`` from its commanded angle; return when it has arrived."""
        self._refuse_if_stopped(f"joint {axis}")
        try:
            cmd.check_axis(axis)
            delta = cmd.quantise(float(delta_deg), self.shell)
        except (InvalidArgumentError, TypeError, ValueError) as exc:
            raise rejected(str(exc)) from exc
        with self._busy():
            start = self._start_commanded()
            plan = self.guard.plan_single_joint_moves(start, [(axis, delta)])
            if not plan.steps:
                log.info("joint %d: %+g deg rounds to no motion", axis, delta_deg)
                return
            self._finish(self._run_plan(plan), plan.end_deg)

    def move_joints(self, target_deg: Sequence[float]) -> None:
        """Move to six absolute joint angles: read ``w0``, move each joint relatively, wait, verify ``w0``."""
        self._refuse_if_stopped("move_joints")
        target = self._target(target_deg)
        self.guard.check_limits(target)
        with self._busy():
            start = self._start_commanded()
            plan = self._plan(target, start)
            self._finish(self._run_plan(plan), tuple(target))

    def _finish(self, reached: tuple[float, ...], target: tuple[float, ...]) -> None:
        axis, diff = worst_axis(reached, target)
        if abs(diff) > self.motion.resolution_deg:
            raise ArrivalError(
                f"after the move the controller commands joint {axis} at {reached[axis - 1]:.3f} deg,"
                f" not the target {target[axis - 1]:.3f} deg; read the position (where) before going on"
            )

    def _compare_pose(self, what: str, w0: PositionReport, pose: Sequence[float] | None) -> None:
        if pose is None:
            return
        axis, diff = worst_axis(w0.joints_deg, pose)
        if abs(diff) > self.motion.pose_tolerance_deg:
            log.warning(
                "%s ended at %s, not the configured pose %s (joint %d off by %+.3f deg): the configured"
                " pose is an assumption; correct it in the settings",
                what,
                _fmt(w0.joints_deg),
                _fmt(pose),
                axis,
                diff,
            )

    def home(self) -> None:
        """Home the arm (the controller chooses the path: not checked by the keep-out); wait for arrival."""
        self._refuse_if_stopped("home")
        with self._busy():
            t0 = self._clock()
            self._command_motion(cmd.HOME, self.link.home_timeout_s)
            w0, w2 = self._wait_still("home", 0.0, self.motion.deadline_margin_s, t0=self._clock())
            self.last_position = RobotPosition(w2.joints_deg, w0.joints_deg, w2.world_mm_deg)
            log.debug("home took %.3f s", self._clock() - t0)
            self._compare_pose("home", w0, self.motion.home_pose_deg)

    def ready(self) -> None:
        """Go to the ready pose (checked when ``SafetyLimits.ready_pose_deg`` is set); wait for arrival.

        Warns (does not fail) when the arm ends elsewhere than the configured ready pose.
        """
        self._refuse_if_stopped("ready")
        with self._busy():
            ready_pose = self.guard.limits.ready_pose_deg
            start = self._read_commanded()
            if ready_pose is not None:
                self.guard.check_linear(start, ready_pose, step=False)
            far = ready_pose or tuple(v + 180.0 for v in start)
            expected, limit = self._motion_deadline(start, far)
            t0 = self._clock()
            self._command_motion(cmd.READY, limit)
            w0, w2 = self._wait_still("ready", expected, limit, t0)
            self.last_position = RobotPosition(w2.joints_deg, w0.joints_deg, w2.world_mm_deg)
            self._compare_pose("ready", w0, ready_pose)

    def set_speed(self, percent: float) -> None:
        """Set the speed override (whole percent 1-100) and read it back."""
        request = cmd.set_speed(percent)
        with self._busy():
            check_silent(request.name, self._run(request))
            reported = parse_speed(self._run(cmd.SPEED_QUERY))
            self._speed_pct = reported
            if reported != float(percent):
                raise DeviceProtocolError(
                    f"speed set to {percent:g}% but the controller reports {reported:g}%"
                )

    def stop(self) -> None:
        """Halt now, best effort, and latch: every motion raises MotionStoppedError until clear_stop().

        Sends the stop sequence (Ctrl-Z by default), then, when no command is in flight, resynchronises
        the line and re-reads the position (``last_position``). Called from another thread while a
        motion runs, it only sends the sequence: that motion resynchronises, re-reads the position and
        raises MotionStoppedError. Never raises a DeviceError (a failure is logged): the E-stop is the
        stop. ``connect()`` does not clear the latch.
        """
        self._stopped.set()
        self._dirty = True
        self._fresh = None
        if not (self._linked and self._transport.is_open):
            log.warning("stop latched on %s (not connected: nothing sent)", self.port_name)
            return
        stop_bytes = self.shell.stop_sequence.encode(self.link.encoding)
        in_flight = self._owner is not None
        try:
            self._transport.write_bytes(stop_bytes)
        except DeviceError as exc:
            log.error("stop: could not send the stop sequence to %s: %s", self.port_name, exc)
            return
        log.warning("stop sent to %s", self.port_name)
        if in_flight or not self._lock.acquire(blocking=False):
            return  # the command in flight resynchronises and reports where the arm is
        try:
            self._resync()
            self.last_position = self._where()
        except DeviceError as exc:
            log.error("stop: could not re-read the position after the stop: %s", exc)
        finally:
            self._lock.release()

    def clear_stop(self) -> None:
        """Release the stop latch: motions are accepted again (read the position first)."""
        self._stopped.clear()

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

    @property
    def last_error(self) -> str | None:
        """The last controller error text seen on this connection."""
        return self._last_error


class _Busy:
    """The robot's lock, remembering the thread holding it (``stop()`` knows a command is in flight)."""

    def __init__(self, robot: CrsA465) -> None:
        self._robot = robot
        self._outer = False

    def __enter__(self) -> None:
        self._robot._lock.acquire()
        self._outer = self._robot._owner is None
        if self._outer:
            self._robot._owner = threading.get_ident()

    def __exit__(self, *exc: object) -> None:
        if self._outer:
            self._robot._owner = None
        self._robot._lock.release()


__all__ = ["Arrival", "CrsA465"]
