"""``FakeRobot``: the arm, acting at once, with the latched stop and the speed cap of the real one."""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence

import numpy as np
import numpy.typing as npt

from station.devices import (
    JOINT_COUNT,
    DeviceConnectionError,
    MotionRejectedError,
    MotionStoppedError,
    RobotPosition,
    RobotStatus,
    StopLatchedError,
)
from station.local_ack import ACKNOWLEDGE_HINT, LocalAcknowledgement, RemoteAcknowledgementError
from station.speed_cap import check_speed
from station.testing._recorder import _FakeDevice

FloatArray = npt.NDArray[np.float64]


class FakeRobot(_FakeDevice):
    """A six-joint arm that moves at once; limits, maximum step and a latched stop like the real driver.

    ``attained_error_deg`` adds a fixed offset to the attained position (to test arrival reporting);
    ``move_time_s`` sleeps in each motion (interruptible by ``stop``), for abort tests.
    """

    MODEL = "fake A465"

    def __init__(
        self,
        start_deg: Sequence[float] = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0),
        *,
        limits_deg: Sequence[tuple[float, float]] | None = None,
        max_step_deg: float = 30.0,
        move_time_s: float = 0.0,
        powered: bool = True,
        homed: bool = True,
        max_speed_pct: float = 100.0,
    ) -> None:
        super().__init__()
        self.joints = np.array(start_deg, dtype=np.float64)
        self.limits = list(
            limits_deg or [(-175.0, 175.0), (-90.0, 110.0), (-110.0, 110.0)] + [(-180.0, 180.0)] * 3
        )
        self.max_step_deg = max_step_deg
        self.move_time_s = move_time_s
        self.powered = powered
        self.homed = homed
        self.speed_pct = min(100.0, max_speed_pct)
        self.max_speed_pct = max_speed_pct
        self.stopped = False
        self._stop_event = threading.Event()
        self.listeners: list[Callable[[FloatArray], None]] = []

    # lifecycle

    # state
    def status(self) -> RobotStatus:
        self._call("status")
        self._require()
        return RobotStatus(power=self.powered, homed=self.homed, moving=False, speed_pct=self.speed_pct)

    def where(self) -> RobotPosition:
        self._call("where")
        self._require()
        j = tuple(float(v) for v in self.joints)
        return RobotPosition(joints_deg=j, commanded_joints_deg=j)

    # motion
    def check_move(
        self, target_deg: Sequence[float] | FloatArray, *, start_deg: Sequence[float] | None = None
    ) -> None:
        target = np.asarray(target_deg, dtype=np.float64)
        start = self.joints if start_deg is None else np.asarray(start_deg, dtype=np.float64)
        if target.shape != (JOINT_COUNT,) or not np.all(np.isfinite(target)):
            raise MotionRejectedError(f"target must be {JOINT_COUNT} finite angles, got {list(target_deg)}")
        for i, (lo, hi) in enumerate(self.limits):
            if not lo <= target[i] <= hi:
                raise MotionRejectedError(
                    f"joint {i + 1} target {target[i]:g} deg is outside {lo:g} to {hi:g}"
                )
        step = np.abs(target - start)
        if step.max() > self.max_step_deg + 1e-9:
            j = int(step.argmax())
            raise MotionRejectedError(
                f"joint {j + 1} would move {step[j]:g} deg in one call, "
                f"more than the {self.max_step_deg:g} allowed"
            )

    def move_joints(self, target_deg: Sequence[float]) -> None:
        self._call("move_joints", tuple(float(v) for v in target_deg))
        self._motion(np.asarray(target_deg, dtype=np.float64))

    def move_joint(self, axis: int, delta_deg: float) -> None:
        self._call("move_joint", axis, delta_deg)
        target = self.joints.copy()
        target[axis - 1] += delta_deg
        self._motion(target)

    def home(self) -> None:
        self._call("home")
        self._require()
        self.homed = True

    def ready(self) -> None:
        self._call("ready")
        self._motion(np.array([0.0, 0.0, 90.0, 0.0, 90.0, 0.0]))

    def set_speed(self, percent: float) -> None:
        self._call("set_speed", percent)
        self._require()
        if not 1 <= percent <= 100:
            raise MotionRejectedError(f"speed {percent} % is outside 1-100 %")
        self.check_speed(percent)
        self.speed_pct = float(percent)

    def stop(self) -> None:
        self.calls.append(("stop", ()))
        self.stopped = True
        self._stop_event.set()

    def clear_stop(self) -> None:
        """As the driver: releases nothing; raises while a stop is latched."""
        self._call("clear_stop")
        if self.stopped:
            raise StopLatchedError(
                f"a stop is latched: it is not cleared by starting again; {ACKNOWLEDGE_HINT}"
            )

    def acknowledge_stop(self, ack: LocalAcknowledgement) -> str | None:
        self._call("acknowledge_stop", ack.source)
        if not isinstance(ack, LocalAcknowledgement) or not ack.fresh():
            raise RemoteAcknowledgementError("a stop is released only by a fresh local acknowledgement")
        was = "stop()" if self.stopped else None
        self.stopped = False
        self._stop_event.clear()
        return was

    def check_speed(self, percent: float) -> None:
        check_speed(percent, self.max_speed_pct)

    def wait_settled(self, timeout_s: float | None = None) -> None:
        self._call("wait_settled", timeout_s)

    def _require(self) -> None:
        if not self.connected:
            raise DeviceConnectionError("fake robot is not connected: call connect() first")

    def _motion(self, target: FloatArray) -> None:
        self._require()
        if self.stopped:
            raise StopLatchedError(f"the robot is stopped (latched); {ACKNOWLEDGE_HINT}")
        self.check_move(target)
        if self.move_time_s and self._stop_event.wait(self.move_time_s):
            raise MotionStoppedError(f"motion stopped by stop(); {ACKNOWLEDGE_HINT}")
        self.joints = target.copy()
        for listener in self.listeners:
            listener(self.joints)


__all__ = [
    "FakeRobot",
]
