"""The CRS A465 on a C500C controller, as a :class:`station.devices.Robot`.

One command at a time: consume the echo, wait for the prompt, look for a controller error, parse the
reply (``_replies``). Motions are checked by the :class:`MotionGuard` before anything is written; an
absolute move is composed from ``w0`` and single-joint relative ``joint`` moves (no absolute
multi-joint command is known for the system shell), then verified against ``w0``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Sequence
from types import TracebackType

import numpy as np
import serial

from drivers.crs_a465 import _commands as cmd
from drivers.crs_a465._commands import Request, ShellProfile
from drivers.crs_a465._errors import CrsControllerError, InvalidArgumentError, find_error, rejected
from drivers.crs_a465._link import LinkSettings, SerialTransport
from drivers.crs_a465._replies import (
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
    DeviceProtocolError,
    DeviceTimeoutError,
    MotionStoppedError,
    RobotPosition,
    RobotStatus,
)
from station.kinematics import Kinematics

log = logging.getLogger(__name__)


class CrsA465:
    """A CRS A465 arm behind a C500C controller's serial console (system or application shell).

    Parameters
    ----------
    port
        A port name (``/dev/ttyS0``), a pyserial URL (``loop://``, ``socket://host:port``, a pty path)
        or an already built ``serial.SerialBase``.
    link
        Serial parameters, line ending, echo and timeouts (:class:`LinkSettings`).
    shell
        The command interpreter (:meth:`ShellProfile.system` by default).
    safety
        Joint limits, maximum step and keep-out checked before any motion (:class:`SafetyLimits`).
    kinematics
        The arm's kinematics for the keep-out (nominal A465 by default).
    position_tolerance_deg
        How far ``w0`` may differ from the target after a composed move (the controller's resolution).
    clock
        Monotonic clock (seconds) for deadlines; injected by tests.
    """

    def __init__(
        self,
        port: str | serial.SerialBase,
        *,
        link: LinkSettings | None = None,
        shell: ShellProfile | None = None,
        safety: SafetyLimits | None = None,
        kinematics: Kinematics | None = None,
        position_tolerance_deg: float = 0.002,
        settle_interval_s: float = 0.05,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link or LinkSettings()
        self.shell = shell or ShellProfile.system()
        self.guard = MotionGuard(safety, kinematics)
        self.position_tolerance_deg = position_tolerance_deg
        self.settle_interval_s = settle_interval_s
        self._clock = clock
        self._transport = SerialTransport(port, self.link, clock=clock)
        self._lock = threading.RLock()
        self._stop_requested = threading.Event()
        self._dirty = True
        self._last_error: str | None = None
        self.last_status: RobotStatus | None = None
        self.last_position: RobotPosition | None = None

    # ---------------------------------------------------------------- link

    @property
    def port_name(self) -> str:
        return str(self._transport.name)

    @property
    def is_connected(self) -> bool:
        return self._transport.is_open

    def connect(self) -> None:
        """Open (or re-open) the link, find the prompt and re-read the arm state."""
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
            log.info(
                "connected to %s: speed %s%%, commanded %s",
                self.port_name,
                self.last_status.speed_pct,
                self.last_position.commanded_joints_deg,
            )

    def close(self) -> None:
        """Close the link; safe to call twice."""
        with self._lock:
            self._transport.close()

    def __enter__(self) -> CrsA465:
        if not self.is_connected:
            self.connect()
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def _resync(self) -> None:
        """Drop stale input and type an empty line until the controller answers with a bare prompt."""
        self._transport.drain()
        self._transport.write_line("")
        deadline = self._clock() + self.link.reply_timeout_s
        while True:
            remaining = max(0.0, deadline - self._clock())
            lines = self._transport.read_until_prompt(self.shell.prompt, remaining, what="(empty line)")
            if not self.link.echo or (lines and lines[-1].strip() == ""):
                break
            log.debug("resync: skipped a late reply %r", lines)
        self._dirty = False

    # ---------------------------------------------------------------- one exchange

    def _timeout(self, request: Request) -> float:
        return {
            "query": self.link.reply_timeout_s,
            "action": self.link.reply_timeout_s,
            "motion": self.link.motion_timeout_s,
            "home": self.link.home_timeout_s,
        }[request.kind]

    def _run(self, request: Request) -> list[str]:
        """Send one command; return its reply lines (echo removed) or raise the controller's error."""
        text = request.text(self.shell)
        if self._dirty:
            self._resync()
        self._transport.write_line(text)
        self._dirty = True  # until the prompt has come, the link is out of step
        lines = self._transport.read_until_prompt(self.shell.prompt, self._timeout(request), what=text)
        self._dirty = False
        if self.link.echo:
            lines = self._strip_echo(text, lines)
        try:
            raise_for_error(text, lines)
        except CrsControllerError as exc:
            self._last_error = exc.controller_text
            raise
        return lines

    def _strip_echo(self, text: str, lines: list[str]) -> list[str]:
        """Remove the echo; lines before it are output nobody asked for (logged, errors remembered)."""
        for i, line in enumerate(lines):
            if line.strip() == text:
                if i:
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

    def _position(self, request: Request) -> PositionReport:
        kind: PositionKind = "commanded" if request is cmd.W0 else "actual"
        return parse_position(self._run(request), expect=kind, command=request.name)

    def _commanded(self) -> tuple[float, ...]:
        return self._position(cmd.W0).joints_deg

    # ---------------------------------------------------------------- reports

    def _status(self) -> RobotStatus:
        speed = parse_speed(self._run(cmd.SPEED_QUERY))
        power: bool | None = None
        homed: bool | None = None
        if self.shell.has_armstat:
            stat = parse_armstat(self._run(cmd.ARMSTAT))
            power, homed = stat.power, stat.homed
        return RobotStatus(
            power=power, homed=homed, moving=None, speed_pct=speed, last_error=self._last_error
        )

    def status(self) -> RobotStatus:
        """Speed (and, on the application shell, power and homing); ``moving`` is not reported (None)."""
        with self._lock:
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
        """Attained (``w2``) and commanded (``w0``) joints, and the WORLD row of the attained position."""
        with self._lock:
            self.last_position = self._where()
            return self.last_position

    # ---------------------------------------------------------------- motions

    def _send_plan(self, plan: PlannedMove) -> None:
        for axis, delta in plan.steps:
            if self._stop_requested.is_set():
                raise MotionStoppedError(f"stopped before joint {axis} moved; re-read the position")
            lines = self._run(cmd.joint(axis, delta, profile=self.shell))
            self._after_motion(f"joint {axis}", lines)
            if not self.shell.motion_blocks:
                self._settle(None)

    def _after_motion(self, what: str, lines: list[str]) -> None:
        marker = self.shell.interrupted_marker
        if marker and any(marker in line for line in lines):
            self._dirty = True
            raise MotionStoppedError(f"{what} was stopped before its end; re-read the position")
        check_silent(what, lines)

    def move_joint(self, axis: int, delta_deg: float) -> None:
        """Move one joint (1-6) by ``delta_deg`` from its commanded angle, after the host checks."""
        try:
            cmd.check_axis(axis)
            delta = cmd.quantise(float(delta_deg), self.shell)
        except (InvalidArgumentError, TypeError, ValueError) as exc:
            raise rejected(str(exc)) from exc
        with self._lock:
            self._stop_requested.clear()
            start = self._commanded()
            plan = self.guard.plan_single_joint_moves(start, [(axis, delta)])
            if not plan.steps:
                log.info("joint %d: %+g deg rounds to no motion", axis, delta_deg)
                return
            self._send_plan(plan)

    def move_joints(self, target_deg: Sequence[float]) -> None:
        """Move to six absolute joint angles: read ``w0``, move each joint relatively, verify ``w0``."""
        try:
            target = [float(v) for v in target_deg]
        except (TypeError, ValueError) as exc:
            raise rejected(f"target must be {JOINT_COUNT} numbers of degrees: {exc}") from exc
        if len(target) != JOINT_COUNT:
            raise rejected(f"target must be {JOINT_COUNT} joint angles, got {len(target)}")
        self.guard.check_limits(target)
        with self._lock:
            self._stop_requested.clear()
            start = self._commanded()
            steps = [(i + 1, cmd.quantise(target[i] - start[i], self.shell)) for i in range(JOINT_COUNT)]
            plan = self.guard.plan_single_joint_moves(start, steps)
            self._send_plan(plan)
            reached = np.asarray(self._commanded())
            error = np.abs(reached - np.asarray(target))
            if np.max(error) > self.position_tolerance_deg:
                axis = int(np.argmax(error)) + 1
                raise DeviceProtocolError(
                    f"after the move the controller commands joint {axis} at {reached[axis - 1]:.3f} deg,"
                    f" not the target {target[axis - 1]:.3f} deg; read the position (where) before going on"
                )

    def home(self) -> None:
        """Home the arm (the controller chooses the path: not checked by the keep-out)."""
        with self._lock:
            self._stop_requested.clear()
            self._after_motion("home", self._run(cmd.HOME))

    def ready(self) -> None:
        """Go to the ready pose; the path is checked when ``SafetyLimits.ready_pose_deg`` is set."""
        with self._lock:
            self._stop_requested.clear()
            ready_pose = self.guard.limits.ready_pose_deg
            if ready_pose is not None:
                self.guard.check_linear(self._commanded(), ready_pose, step=False)
            self._after_motion("ready", self._run(cmd.READY))

    def set_speed(self, percent: float) -> None:
        """Set the speed override (whole percent 1-100) and read it back."""
        request = cmd.set_speed(percent)
        with self._lock:
            check_silent(request.name, self._run(request))
            reported = parse_speed(self._run(cmd.SPEED_QUERY))
            if reported != float(percent):
                raise DeviceProtocolError(
                    f"speed set to {percent:g}% but the controller reports {reported:g}%"
                )

    def stop(self) -> None:
        """Send the stop sequence now; a motion in progress ends with MotionStoppedError."""
        self._stop_requested.set()
        stop_bytes = self.shell.stop_sequence.encode(self.link.encoding)
        if self._lock.acquire(blocking=False):
            try:
                if self._transport.is_open:
                    self._transport.write_bytes(stop_bytes)
                    self._dirty = True  # the controller answers with a prompt nobody asked for
            finally:
                self._lock.release()
        else:  # a command is in flight: its reader will see the controller's answer
            self._transport.write_bytes(stop_bytes)
        log.warning("stop sent to %s", self.port_name)

    def _settle(self, timeout_s: float | None) -> None:
        deadline = None if timeout_s is None else self._clock() + timeout_s
        previous = np.asarray(self._position(cmd.W2).joints_deg)
        while True:
            if deadline is not None and self._clock() > deadline:
                raise DeviceTimeoutError(f"the arm did not settle within {timeout_s:g} s")
            time.sleep(self.settle_interval_s)
            current = np.asarray(self._position(cmd.W2).joints_deg)
            if np.max(np.abs(current - previous)) <= self.position_tolerance_deg / 2:
                return
            previous = current

    def wait_settled(self, timeout_s: float | None = None) -> None:
        """Return when the arm is still: at once if motions block, else when ``w2`` stops changing."""
        if not self._lock.acquire(timeout=-1 if timeout_s is None else timeout_s):
            raise DeviceTimeoutError(f"a motion was still in progress after {timeout_s:g} s")
        try:
            if not self.shell.motion_blocks:
                self._settle(timeout_s)
        finally:
            self._lock.release()

    @property
    def last_error(self) -> str | None:
        """The last controller error text seen on this connection."""
        return self._last_error


__all__ = ["CrsA465"]
