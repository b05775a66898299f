"""The simulated A465 arm behind the twin's shell: state, timed motion and repeatability error.

Motion: every joint of a move follows one trapezoidal velocity profile (the slowest joint's), so a
move is a straight line in joint space, as the host's keep-out check assumes. Joint speed is the
joint's maximum times the speed override; acceleration is not scaled [A]. ``time_scale`` divides
every duration (100 runs the arm 100x faster than real).

Attained position: when a joint moves, it stops at the commanded angle plus a systematic offset,
plus a backlash term signed by the direction of approach, plus Gaussian noise, plus a servo residual
that decays after the motion's end (``sim.arm_errors``); then the encoder quantises it
(``counts_per_deg``). A joint that did not move keeps its attained angle.
"""

from __future__ import annotations

import logging
import math
import threading
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from sim.arm_errors import attained_error, settle_residual, settle_start
from station.kinematics import Kinematics

log = logging.getLogger(__name__)

FloatArray = npt.NDArray[np.float64]
JOINTS = 6


class ArmError(Exception):
    """A controller error text (``'001 Joint 1 limit exceeded'``) raised by the arm model."""

    def __init__(self, text: str) -> None:
        super().__init__(text)
        self.text = text


def trapezoid_time(distance: float, speed: float, accel: float) -> float:
    """Duration (s) of a rest-to-rest trapezoidal (or triangular) move."""
    if distance <= 0.0:
        return 0.0
    if distance >= speed * speed / accel:
        return distance / speed + speed / accel
    return 2.0 * math.sqrt(distance / accel)


def trapezoid_fraction(t: float, distance: float, speed: float, accel: float) -> float:
    """Fraction (0-1) of ``distance`` covered at time ``t`` of that move."""
    total = trapezoid_time(distance, speed, accel)
    if distance <= 0.0 or t >= total:
        return 1.0
    if t <= 0.0:
        return 0.0
    if distance >= speed * speed / accel:
        ta, vp = speed / accel, speed
    else:
        ta = total / 2.0
        vp = accel * ta
    if t < ta:
        s = 0.5 * accel * t * t
    elif t <= total - ta:
        s = 0.5 * accel * ta * ta + vp * (t - ta)
    else:
        r = total - t
        s = distance - 0.5 * accel * r * r
    return min(1.0, max(0.0, s / distance))


@dataclass(frozen=True)
class MotionRecord:
    """One executed move, as the controller commanded it (for tests and demos)."""

    kind: str
    start_deg: tuple[float, ...]
    end_deg: tuple[float, ...]
    stopped: bool = False


@dataclass
class _Motion:
    cmd_start: FloatArray
    cmd_end: FloatArray
    att_start: FloatArray
    att_end: FloatArray
    t0: float
    duration_s: float  # real (scaled) seconds
    lead_distance: float
    lead_speed: float
    lead_accel: float
    time_scale: float
    kind: str

    def fraction(self, now: float) -> float:
        return trapezoid_fraction(
            (now - self.t0) * self.time_scale, self.lead_distance, self.lead_speed, self.lead_accel
        )


@dataclass(frozen=True)
class ArmParameters:
    """The arm model's settings (see :class:`sim._controller_settings.TwinSettings` for their meaning)."""

    max_speed_deg_s: tuple[float, ...]
    accel_deg_s2: tuple[float, ...]
    counts_per_deg: tuple[float, ...]
    repeat_sigma_deg: tuple[float, ...]
    systematic_deg: tuple[float, ...]
    backlash_deg: tuple[float, ...]
    home_pose_deg: tuple[float, ...]
    ready_pose_deg: tuple[float, ...]
    start_pose_deg: tuple[float, ...]
    homing_extra_s: float
    time_scale: float
    log_limit: int = 1000
    settle_deg: tuple[float, ...] = (0.0,) * JOINTS
    settle_time_s: float = 0.05


class Arm:
    """Power, homing, speed, limp axes and the timed motion of the simulated arm (thread-safe)."""

    def __init__(
        self,
        params: ArmParameters,
        kinematics: Kinematics,
        *,
        power: bool,
        homed: bool,
        speed_pct: int,
        rng: np.random.Generator,
        clock: Callable[[], float],
    ) -> None:
        self.params = params
        self.kinematics = kinematics
        self.power = power
        self.homed = homed
        self.speed_pct = speed_pct
        self.limp: set[int] = set()
        self._rng = rng
        self._clock = clock
        self._lock = threading.RLock()
        start = np.asarray(params.start_pose_deg, dtype=float)
        self._cmd = start.copy()
        self._att = start.copy()
        self._motion: _Motion | None = None
        self.motion_log: deque[MotionRecord] = deque(maxlen=params.log_limit)  # the last N moves
        self.moves = 0  # motions started: the world's Cartesian error changes with each
        self._settle = np.zeros(JOINTS)  # each joint's servo residual (deg) at the end of its last motion
        self._settle_t0 = np.zeros(JOINTS)  # and when that motion ended (clock)

    # ---------------------------------------------------------------- reading

    def _update(self) -> None:
        m = self._motion
        if m is not None and self._clock() >= m.t0 + m.duration_s:
            self._cmd, self._att = m.cmd_end.copy(), m.att_end.copy()
            self._motion = None

    def moving(self) -> bool:
        with self._lock:
            self._update()
            return self._motion is not None

    def axes_done(self) -> list[bool]:
        """Per axis, whether it has finished moving (armstat's ``done`` column)."""
        with self._lock:
            self._update()
            m = self._motion
            if m is None:
                return [True] * JOINTS
            return [bool(d == 0.0) for d in (m.cmd_end - m.cmd_start)]

    def remaining_s(self) -> float:
        """Real seconds until the current motion ends (0 when still)."""
        with self._lock:
            self._update()
            m = self._motion
            return 0.0 if m is None else max(0.0, m.t0 + m.duration_s - self._clock())

    def commanded(self) -> FloatArray:
        """The set-point now (deg): on the way during a motion, the target after it."""
        with self._lock:
            self._update()
            m = self._motion
            if m is None:
                return self._cmd.copy()
            s = m.fraction(self._clock())
            return np.asarray(m.cmd_start + s * (m.cmd_end - m.cmd_start), dtype=float)

    def actual_exact(self) -> FloatArray:
        """Where the joints are now (deg), before encoder quantisation."""
        with self._lock:
            self._update()
            m = self._motion
            now = self._clock()
            elapsed = (now - self._settle_t0) * self.params.time_scale
            settling = settle_residual(self._settle, elapsed, self.params.settle_time_s)
            if m is None:
                return self._att + settling
            s = m.fraction(now)
            return np.asarray(m.att_start + s * (m.att_end - m.att_start) + settling, dtype=float)

    def pulses(self, joints_deg: FloatArray) -> list[int]:
        return [round(v * c) for v, c in zip(joints_deg, self.params.counts_per_deg, strict=True)]

    def actual(self) -> FloatArray:
        """Where the encoders say the joints are (deg)."""
        counts = np.asarray(self.params.counts_per_deg, dtype=float)
        return np.asarray(self.pulses(self.actual_exact()), dtype=float) / counts

    # ---------------------------------------------------------------- checks

    def _require(self, *, power: bool = True, homed: bool = True, axes: Sequence[int] = ()) -> None:
        if power and not self.power:
            raise ArmError("007 Arm power is OFF")
        if homed and not self.homed:
            raise ArmError("005 Not homed or not calibrated")
        for axis in axes:
            if axis in self.limp:
                raise ArmError(f"004 Axis {axis} is limp")

    def _check_limits(self, target: FloatArray) -> None:
        for i, (lo, hi) in enumerate(self.kinematics.joint_limits_deg):
            if not lo - 1e-9 <= target[i] <= hi + 1e-9:
                raise ArmError(f"001 Joint {i + 1} limit exceeded")

    # ---------------------------------------------------------------- motion

    def _attained(self, cmd_end: FloatArray, delta: FloatArray, previous: FloatArray) -> FloatArray:
        p = self.params
        error = attained_error(
            self._rng,
            delta,
            sigma_deg=p.repeat_sigma_deg,
            backlash_deg=p.backlash_deg,
            systematic_deg=p.systematic_deg,
        )
        moved = np.abs(delta) > 0.0
        self._settle = np.where(moved, settle_start(self._rng, moved, p.settle_deg), self._settle)
        return np.where(moved, cmd_end + error, previous)

    def _start(self, target: FloatArray, kind: str) -> float:
        """Start a synchronised move to ``target`` (deg); return its real duration (s)."""
        self._update()
        if self._motion is not None:
            raise ArmError("arm is busy")  # the server waits for the arm before it dispatches a motion
        p = self.params
        start = self._cmd.copy()
        delta = target - start
        speeds = np.asarray(p.max_speed_deg_s) * self.speed_pct / 100.0
        accels = np.asarray(p.accel_deg_s2)
        times = [trapezoid_time(abs(d), v, a) for d, v, a in zip(delta, speeds, accels, strict=True)]
        lead = int(np.argmax(times))
        duration = times[lead] / p.time_scale
        att_end = self._attained(target, delta, self._att)
        self.moves += 1
        self._settle_t0 = np.where(np.abs(delta) > 0.0, self._clock() + duration, self._settle_t0)
        self.motion_log.append(MotionRecord(kind, tuple(start.tolist()), tuple(target.tolist())))
        if duration <= 0.0:
            self._cmd, self._att = target.copy(), att_end
            return 0.0
        self._motion = _Motion(
            cmd_start=start,
            cmd_end=target.copy(),
            att_start=self._att.copy(),
            att_end=att_end,
            t0=self._clock(),
            duration_s=duration,
            lead_distance=abs(float(delta[lead])),
            lead_speed=float(speeds[lead]),
            lead_accel=float(accels[lead]),
            time_scale=p.time_scale,
            kind=kind,
        )
        log.debug("%s: %s -> %s in %.3f s", kind, start.round(3).tolist(), target.round(3).tolist(), duration)
        return duration

    def move_joint(self, axis: int, delta_deg: float) -> float:
        """``joint AXIS DEG``: relative to the commanded angle; returns the duration (s)."""
        with self._lock:
            self._require(axes=[axis])
            self._update()
            target = self._cmd.copy()
            target[axis - 1] += delta_deg
            self._check_limits(target)
            return self._start(target, f"joint {axis}")

    def move_to(self, target_deg: Sequence[float], kind: str) -> float:
        """An absolute synchronised move (``ready``)."""
        with self._lock:
            self._require(axes=range(1, JOINTS + 1))
            target = np.asarray(target_deg, dtype=float)
            self._check_limits(target)
            return self._start(target, kind)

    def home(self) -> float:
        """``home``: needs power, not homing; ends homed at the home pose."""
        with self._lock:
            self._require(homed=False, axes=range(1, JOINTS + 1))
            duration = self._start(np.asarray(self.params.home_pose_deg, dtype=float), "home")
            self.homed = True
            return duration + self.params.homing_extra_s / self.params.time_scale

    def calibrate_at_ready(self) -> None:
        """``calrdy``: the arm is declared at the ready pose and calibrated there [A]."""
        with self._lock:
            self._require(homed=False)
            ready = np.asarray(self.params.ready_pose_deg, dtype=float)
            self._cmd, self._att = ready.copy(), ready.copy()
            self._motion = None
            self.homed = True

    def stop(self) -> None:
        """Freeze the arm where it is now (commanded and attained)."""
        with self._lock:
            self._update()
            m = self._motion
            if m is None:
                return
            now_cmd, now_att = self.commanded(), self.actual_exact()
            self._cmd, self._att = now_cmd, now_att
            self._motion = None
            self._settle = np.zeros(JOINTS)  # frozen where it is, residual included
            last = self.motion_log[-1]
            self.motion_log[-1] = MotionRecord(
                last.kind, last.start_deg, tuple(now_cmd.tolist()), stopped=True
            )
            log.debug("stopped at %s", now_cmd.round(3).tolist())

    def set_power(self, on: bool) -> None:
        with self._lock:
            if not on:
                self.stop()
            self.power = on
