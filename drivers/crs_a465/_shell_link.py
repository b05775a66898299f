"""The C500C's console as a session of exchanges: the link, one command at a time, the reports.

The first layer of :class:`drivers.crs_a465.CrsA465`: open and resynchronise the line, send one command,
consume its echo, wait for the prompt, recognise a controller error, parse the reply (``_replies``), and
the reports (``status``, ``where``, ``identity``). Motions, their waits and the stop latch are the layers
above (``_waits``, ``_robot``).
"""

from __future__ import annotations

import logging
import os
import re
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Self

import serial

from drivers.crs_a465 import _commands as cmd
from drivers.crs_a465._commands import Request, ShellProfile
from drivers.crs_a465._errors import (
    HALT_NOTICE,
    POINT_OF_CONTROL,
    CrsControllerError,
    error_of_line,
    find_error,
    unexpected,
)
from drivers.crs_a465._latch import StopLatch
from drivers.crs_a465._link import LinkSettings, SerialTransport
from drivers.crs_a465._motion import (
    MotionSettings,
)
from drivers.crs_a465._replies import (
    ArmStat,
    PositionKind,
    PositionReport,
    check_printable,
    parse_armstat,
    parse_position,
    parse_speed,
    raise_for_error,
)
from drivers.crs_a465._safety import MotionGuard, SafetyLimits
from station.devices import (
    DeviceIdentity,
    DeviceProtocolError,
    DeviceTimeoutError,
    RobotPosition,
    RobotStatus,
)
from station.kinematics import Kinematics

log = logging.getLogger(__name__)

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


class _ShellLink:
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
    latch_file
        Where the stop latch is kept across processes (``_latch``; the station's data directory);
        ``None``: in this object only.
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
        latch_file: str | os.PathLike[str] | None = None,
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
        self.latch = StopLatch(latch_file)
        self._stopped = self.latch.event  # set: every motion refused until acknowledged at the station
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
        """Whether the stop latch is set (motions refused until acknowledged at the station)."""
        return self._stopped.is_set()

    @property
    def latch_reason(self) -> str | None:
        """What set the stop latch (``None`` when it is not set)."""
        return self.latch.reason if self.latch.is_set() else None

    def _latch_now(self, reason: str) -> None:
        """Set the stop latch: a stop, a halt, an E-stop or a controller error during a motion."""
        if not self.latch.is_set():
            log.warning("%s: stop latched: %s", self.port_name, reason)
        self.latch.set(reason)

    def connect(self) -> None:
        """Open (or re-open) the link, find the prompt and re-read the arm state (a stop stays latched;
        one acknowledged or latched by another process of the station, through the latch file, is
        followed)."""
        with self._lock:
            self.latch.sync()
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

    def __enter__(self) -> Self:
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
            self._latch_now("the controller halted the robot (^Z detected)")
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

    def _busy(self) -> _Busy:
        return _Busy(self)

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

    @property
    def last_error(self) -> str | None:
        """The last controller error text seen on this connection."""
        return self._last_error


class _Busy:
    """The robot's lock, remembering the thread holding it (``stop()`` knows a command is in flight)."""

    def __init__(self, robot: _ShellLink) -> None:
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


__all__ = ["Arrival"]
