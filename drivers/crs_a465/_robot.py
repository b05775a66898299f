"""The CRS A465 on a C500C controller, as a :class:`station.devices.Robot`.

Three layers: ``_shell_link`` (one command at a time: echo, prompt, controller errors, the reports),
``_waits`` (a motion command sent and waited for until the arm has arrived) and this one, the motions
and their host checks. Every motion is checked by the :class:`MotionGuard` before anything is written
(limits, step, keep-out along the path) and runs at a speed within the station's cap; an absolute move
is composed from ``w0`` and single-joint relative ``joint`` moves (the system shell has no absolute
multi-joint command [F]). The readings that proved an arrival stand for :meth:`CrsA465.where` and for
the next move's start while nothing has been sent since and for at most ``MotionSettings.reuse_s``.

**The stop latch.** ``stop()``, a halt at the controller, an E-stop (the arm's power seen going off) and
any controller error during a motion latch: every motion then raises
:class:`station.local_ack.StopLatchedError` until :meth:`CrsA465.acknowledge_stop` is given a
:class:`station.local_ack.LocalAcknowledgement`, which only the station's own terminal or a loopback
request can make. ``clear_stop()`` (what a session's start calls) releases nothing. The stop itself is
best effort: it sends the halt key (Ctrl-Z by default), resynchronises the line and re-reads the
position. On a real arm the E-stop is the stop.
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator, Sequence

from drivers.crs_a465 import _commands as cmd
from drivers.crs_a465._errors import (
    ArrivalError,
    CrsControllerError,
    InvalidArgumentError,
    NotHomedError,
    rejected,
)
from drivers.crs_a465._motion import worst_axis
from drivers.crs_a465._replies import PositionReport, check_silent, parse_speed
from drivers.crs_a465._safety import PlannedMove
from drivers.crs_a465._shell_link import Arrival, _fmt
from drivers.crs_a465._waits import _Waits
from station.devices import (
    JOINT_COUNT,
    DeviceConnectionError,
    DeviceError,
    DeviceProtocolError,
    RobotPosition,
    RobotStatus,
    StopLatchedError,
)
from station.local_ack import ACKNOWLEDGE_HINT, LocalAcknowledgement
from station.speed_cap import SpeedCapError

log = logging.getLogger(__name__)


class CrsA465(_Waits):
    """A CRS A465 arm behind a C500C controller's serial console (system or application shell); the
    constructor's parameters are :class:`drivers.crs_a465._shell_link._ShellLink`'s."""

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

    def check_speed(self, percent: float) -> None:
        """Raise what ``set_speed(percent)`` would raise on the host (the speed cap), with no I/O."""
        self.guard.check_speed(percent)

    def _refuse_if_stopped(self, what: str) -> None:
        if self._stopped.is_set():
            raise StopLatchedError(
                f"{what} refused: a stop is latched ({self.latch.reason}); {ACKNOWLEDGE_HINT}",
                reason=self.latch.reason or "",
            )

    def _refuse_over_cap(self, what: str) -> None:
        """No motion at a speed override above the cap (the pendant or an earlier program may have set it)."""
        if self._speed_pct is None:
            self._speed_pct = parse_speed(self._run(cmd.SPEED_QUERY))
        cap = self.guard.limits.max_speed_pct
        if self._speed_pct > cap + 1e-9:
            raise SpeedCapError(
                f"{what} refused: the controller's speed override is {self._speed_pct:g} %, above the"
                f" station's cap of {cap:g} % (max_speed_pct in [robot] safety of station.toml): set it"
                f" to {cap:g} % or less first (station robot ... speed {cap:g})",
                requested=self._speed_pct,
                cap=cap,
            )

    @contextlib.contextmanager
    def _latching(self, what: str) -> Iterator[None]:
        """A controller error or a bad arrival during a motion latches the stop, then propagates (all
        but "not homed", a refusal to start)."""
        try:
            yield
        except NotHomedError:
            raise  # a refusal to start (nothing moved) whose remedy, home, is itself checked
        except (CrsControllerError, ArrivalError) as exc:
            self._latch_now(f"{what}: {exc}")
            raise

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
            self._refuse_over_cap(f"joint {axis}")
            with self._latching(f"joint {axis} {delta:+g}"):
                self._finish(self._run_plan(plan), plan.end_deg)

    def move_joints(self, target_deg: Sequence[float]) -> None:
        """Move to six absolute joint angles: read ``w0``, move each joint relatively, wait, verify ``w0``."""
        self._refuse_if_stopped("move_joints")
        target = self._target(target_deg)
        self.guard.check_limits(target)
        with self._busy():
            start = self._start_commanded()
            plan = self._plan(target, start)
            if plan.steps:
                self._refuse_over_cap("move_joints")
            with self._latching(f"move to {_fmt(target)}"):
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
        """Home the arm; wait for arrival.

        The controller chooses the path: homes axis by axis [F], to a home pose that is an assumption
        (``SafetyLimits.home_pose_deg``, all zeros). Both ways it could go are checked against the
        keep-out before ``home`` is sent: all joints together in joint space, and one axis at a time in
        the order 1 to 6. ``home_pose_deg = None`` refuses it (the path would be unknown).
        """
        self._refuse_if_stopped("home")
        home_pose = self.guard.limits.home_pose_deg
        if home_pose is None:
            raise rejected(
                "home refused: its path cannot be checked without SafetyLimits.home_pose_deg (where home"
                " goes); set it, or home the arm from the pendant with the cell watched"
            )
        with self._busy():
            start = self._read_commanded()
            self.guard.check_home(start, home_pose)
            self._refuse_over_cap("home")
            t0 = self._clock()
            with self._latching("home"):
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
            if ready_pose is None:
                raise rejected(
                    "ready refused: its path cannot be checked without SafetyLimits.ready_pose_deg (where"
                    " ready goes); set it"
                )
            self.guard.check_linear(start, ready_pose, step=False)
            self._refuse_over_cap("ready")
            expected, limit = self._motion_deadline(start, ready_pose)
            t0 = self._clock()
            with self._latching("ready"):
                self._command_motion(cmd.READY, limit)
                w0, w2 = self._wait_still("ready", expected, limit, t0)
            self.last_position = RobotPosition(w2.joints_deg, w0.joints_deg, w2.world_mm_deg)
            self._compare_pose("ready", w0, ready_pose)

    def set_speed(self, percent: float) -> None:
        """Set the speed override (whole percent 1-100, at most ``max_speed_pct``) and read it back.

        A speed above the station's cap raises :class:`station.speed_cap.SpeedCapError` (saying the cap
        and where it is set) before anything is sent.
        """
        request = cmd.set_speed(percent)
        self.guard.check_speed(percent)
        with self._busy():
            check_silent(request.name, self._run(request))
            reported = parse_speed(self._run(cmd.SPEED_QUERY))
            self._speed_pct = reported
            if reported != float(percent):
                raise DeviceProtocolError(
                    f"speed set to {percent:g}% but the controller reports {reported:g}%"
                )

    def stop(self) -> None:
        """Halt now, best effort, and latch: every motion raises StopLatchedError until acknowledge_stop().

        Sends the stop sequence (Ctrl-Z by default), then, when no command is in flight, resynchronises
        the line and re-reads the position (``last_position``). Called from another thread while a
        motion runs, it only sends the sequence: that motion resynchronises, re-reads the position and
        raises MotionStoppedError. Never raises a DeviceError (a failure is logged): the E-stop is the
        stop. ``connect()`` does not clear the latch.
        """
        self._latch_now("stop() from the host (a session's abort or stop, Ctrl-C, the page)")
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
        """Release nothing: with no stop latched it does nothing; with one, it raises StopLatchedError
        saying how to acknowledge it at the station (:meth:`acknowledge_stop`). A session's start calls
        this, so no session clears a latch by itself."""
        if self._stopped.is_set():
            raise StopLatchedError(
                f"a stop is latched ({self.latch.reason}): it is not cleared by starting again; "
                + ACKNOWLEDGE_HINT,
                reason=self.latch.reason or "",
            )

    def acknowledge_stop(self, ack: LocalAcknowledgement) -> str | None:
        """Release the stop latch with a person's acknowledgement at the station; return what latched it
        (``None``: nothing was latched). Anything but a fresh, unused :class:`LocalAcknowledgement`
        raises :class:`station.local_ack.RemoteAcknowledgementError` and releases nothing."""
        return self.latch.acknowledge(ack)

    def status(self) -> RobotStatus:
        """Speed, and from armstat power, calibration, homing, motion (its ``done`` column), arm type.

        The arm's power seen going off after it was on (an E-stop, or the power switch) latches the stop.
        """
        was_on = self.last_status is not None and self.last_status.power is True
        status = super().status()
        if was_on and status.power is False:
            self._latch_now("the arm's power went off (an E-stop, or the power switch)")
        return status


__all__ = ["Arrival", "CrsA465"]
