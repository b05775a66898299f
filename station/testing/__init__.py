"""In-process fakes of every device, for fast plan and runner tests (the *mock* tier; ``sim/`` is the
realistic tier).

Each fake satisfies its protocol in ``station.devices``, acts at once, records every call in ``calls``
(``(method, args)`` tuples, in order) and can be told to fail: ``fail_on("move_joints", exc, nth=3)``
raises ``exc`` on the third call of that method. Assertion helpers (``assert_called``,
``assert_not_called``, ``calls_of``) keep test bodies short. ``FakeCamera`` serves the frames it is
given, or draws a crossed-groove artifact whose crossing moves with the fake robot and table
(``Scene``), so that the measurement core measures real positions in plan tests.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from station.config import (
    CameraConfig,
    DistanceSensorConfig,
    RobotConfig,
    StationConfig,
    StationDevices,
    TableConfig,
)
from station.devices import (
    JOINT_COUNT,
    CameraStatus,
    DeviceConnectionError,
    DeviceIdentity,
    DistanceSensorStatus,
    Frame,
    ImageArray,
    MotionRejectedError,
    MotionStoppedError,
    OutOfRangeError,
    RobotPosition,
    RobotStatus,
    SensorAlarmError,
    StopLatchedError,
    TablePosition,
    grab_frames,
)
from station.local_ack import ACKNOWLEDGE_HINT, LocalAcknowledgement, RemoteAcknowledgementError
from station.prompts import PromptBroker
from station.speed_cap import check_speed

FloatArray = npt.NDArray[np.float64]


class _Recorder:
    """Call log and scripted failures shared by the fakes."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self._failures: dict[str, list[tuple[int, BaseException]]] = {}
        self._counts: dict[str, int] = {}
        self._rec_lock = threading.Lock()

    def fail_on(self, method: str, exc: BaseException, *, nth: int = 1) -> None:
        """Raise ``exc`` on the ``nth`` call of ``method`` from now on (1 = the next call)."""
        with self._rec_lock:
            done = self._counts.get(method, 0)
            self._failures.setdefault(method, []).append((done + nth, exc))

    def _call(self, method: str, *args: Any) -> None:
        with self._rec_lock:
            self.calls.append((method, args))
            n = self._counts[method] = self._counts.get(method, 0) + 1
            for i, (when, exc) in enumerate(self._failures.get(method, [])):
                if when == n:
                    del self._failures[method][i]
                    raise exc

    def calls_of(self, method: str) -> list[tuple[Any, ...]]:
        return [args for name, args in self.calls if name == method]

    def assert_called(self, method: str, times: int | None = None) -> None:
        n = len(self.calls_of(method))
        if (times is None and n == 0) or (times is not None and n != times):
            want = "at least once" if times is None else f"{times} time(s)"
            raise AssertionError(f"{type(self).__name__}.{method} called {n} time(s), expected {want}")

    def assert_not_called(self, method: str) -> None:
        self.assert_called(method, 0)


class _FakeDevice(_Recorder):
    """The lifecycle every fake shares: ``connect``/``close`` recorded, ``identity`` from ``MODEL``."""

    MODEL = "fake device"

    def __init__(self) -> None:
        super().__init__()
        self.connected = False

    def connect(self) -> None:
        self._call("connect")
        self.connected = True

    def close(self) -> None:
        self._call("close")
        self.connected = False

    def identity(self) -> DeviceIdentity:
        return DeviceIdentity(model=self.MODEL, serial="fake-1", port="in-process", firmware=None)


# --------------------------------------------------------------------------- robot


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


# --------------------------------------------------------------------------- table


class FakeTable(_FakeDevice):
    """An X-Y table that moves at once within its travel (mm); no operator."""

    MODEL = "fake X-Y table"

    def __init__(self, travel_mm: tuple[float, float] = (-12.7, 12.7)) -> None:
        super().__init__()
        self.travel_mm = travel_mm
        self.pos = TablePosition(0.0, 0.0)

    def check_target(self, x_mm: float, y_mm: float) -> None:
        lo, hi = self.travel_mm
        for axis, v in (("x", x_mm), ("y", y_mm)):
            if not math.isfinite(v) or not lo <= v <= hi:
                raise MotionRejectedError(f"table {axis} = {v} mm is outside its travel {lo} to {hi} mm")

    def position(self) -> TablePosition:
        return self.pos

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        self._call("move_to", x_mm, y_mm)
        if not self.connected:
            raise DeviceConnectionError("fake table is not connected: call connect() first")
        self.check_target(x_mm, y_mm)
        self.pos = TablePosition(float(x_mm), float(y_mm))
        return self.pos


# --------------------------------------------------------------------------- camera


def draw_cross(
    shape: tuple[int, int] = (480, 640),
    center_px: tuple[float, float] = (320.0, 240.0),
    *,
    groove_width_px: float = 79.375,
    angle_deg: float = 2.0,
    blur_px: float = 1.2,
    noise: float = 2.0,
    rng: np.random.Generator | None = None,
) -> npt.NDArray[np.uint8]:
    """A crossed-groove artifact image: dark paint-filled grooves on a bright land, smooth edges.

    Edges are error-function profiles of width ``blur_px`` around the exact groove borders, so the
    crossing's true position is ``center_px`` to well below 0.01 px. Vectorised; no pixel loops. The
    default width is the artifact's nominal 1/32 in (0.79375 mm) at the fake scene's 100 px/mm, so that a
    validation on the fakes estimates a width inside the artifact's tolerance band (its gate).
    """
    from scipy.special import erf

    h, w = shape
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    a = math.radians(angle_deg)
    dx, dy = x - center_px[0], y - center_px[1]
    u = dx * math.cos(a) + dy * math.sin(a)  # along the horizontal groove
    v = -dx * math.sin(a) + dy * math.cos(a)
    half = groove_width_px / 2.0
    s = blur_px * math.sqrt(2.0)

    # The band profile is tabulated finely once and interpolated (np.interp is ~50x cheaper than erf).
    reach = half + 8.0 * s
    table_d = np.linspace(-reach, reach, int(2 * reach / 0.005) + 1)
    table_b = 0.5 * (erf((half - table_d) / s) - erf((-half - table_d) / s))

    def band(d: FloatArray) -> FloatArray:
        return np.interp(d, table_d, table_b, left=0.0, right=0.0)

    groove = np.maximum(band(v), band(u))
    image = 200.0 - 150.0 * groove
    if noise:
        image += (rng or np.random.default_rng(0)).normal(0.0, noise, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@dataclass
class Scene:
    """Where the fake camera sees the crossing: it moves ``px_per_mm`` per mm of table travel (against
    the table's motion) and ``px_per_deg`` per degree of each joint away from ``reference_deg``."""

    robot: FakeRobot | None = None
    table: FakeTable | None = None
    reference_deg: tuple[float, ...] = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)
    px_per_mm: float = 100.0
    px_per_deg: tuple[float, ...] = (40.0, 30.0, 25.0, 20.0, 20.0, 0.0)
    center_px: tuple[float, float] = (320.0, 240.0)

    def crossing_px(self) -> tuple[float, float]:
        cx, cy = self.center_px
        if self.table is not None:
            cx -= self.table.pos.x_mm * self.px_per_mm
            cy -= self.table.pos.y_mm * self.px_per_mm
        if self.robot is not None:
            d = self.robot.joints - np.asarray(self.reference_deg)
            shift = float(np.dot(d, self.px_per_deg))
            cx += shift
            cy += 0.5 * shift
        return cx, cy


class FakeCamera(_FakeDevice):
    """A camera that serves the frames it is given (in order, then the last one again as a new frame), or
    draws the artifact where ``scene`` puts it. ``grab_time_s`` sleeps in each grab."""

    MODEL = "fake camera"

    def __init__(
        self,
        frames: Iterable[ImageArray] | None = None,
        *,
        scene: Scene | None = None,
        seed: int = 0,
        grab_time_s: float = 0.0,
    ) -> None:
        super().__init__()
        self._frames = list(frames) if frames is not None else None
        self.scene = scene or Scene()
        self._rng = np.random.default_rng(seed)
        self.grab_time_s = grab_time_s
        self._next_id = 1

    def grab(self, timeout_s: float = 2.0) -> Frame:
        self._call("grab", timeout_s)
        if not self.connected:
            raise DeviceConnectionError("fake camera is not connected: call connect() first")
        if self.grab_time_s:
            time.sleep(self.grab_time_s)
        if self._frames is not None:
            image = self._frames[min(self._next_id - 1, len(self._frames) - 1)]
        else:
            image = draw_cross(center_px=self.scene.crossing_px(), rng=self._rng)
        frame = Frame(image=image, timestamp_s=time.time(), frame_id=self._next_id)
        self._next_id += 1
        return frame

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        return grab_frames(self.grab, count, average=average, timeout_s=timeout_s)

    def status(self) -> CameraStatus:
        return CameraStatus(
            connected=self.connected, model="fake camera", width=640, height=480, pixel_format="Mono8"
        )


# --------------------------------------------------------------------------- distance sensor


class FakeDistanceSensor(_FakeDevice):
    """A distance sensor that reads ``distance()`` (mm; ``None``: no target) at once.

    Outside ``measuring_range_mm`` or ``None``: ``OutOfRangeError``; ``alarm = True``:
    ``SensorAlarmError``; any other failure through ``fail_on("read_mm", exc)``.
    """

    MODEL = "fake distance sensor"

    def __init__(
        self,
        distance: Callable[[], float | None] | float | None = 68.0,
        *,
        measuring_range_mm: tuple[float, float] = (55.0, 105.0),
    ) -> None:
        super().__init__()
        self._distance = distance if callable(distance) else (lambda: distance)
        self._range = measuring_range_mm
        self.alarm = False

    @property
    def measuring_range_mm(self) -> tuple[float, float]:
        return self._range

    def read_mm(self) -> float:
        self._call("read_mm")
        if not self.connected:
            raise DeviceConnectionError("fake distance sensor: connect() first")
        if self.alarm:
            raise SensorAlarmError("fake distance sensor: alarm", reply="alarm")
        d = self._distance()
        near, far = self._range
        if d is None or not near <= d <= far:
            raise OutOfRangeError(
                f"fake distance sensor: no target within its measuring range {near}-{far} mm", reply=str(d)
            )
        return float(d)

    def status(self) -> DistanceSensorStatus:
        try:
            d = self.read_mm()
        except OutOfRangeError as exc:
            return DistanceSensorStatus("out_of_range", str(exc))
        except SensorAlarmError as exc:
            return DistanceSensorStatus("alarm", str(exc))
        return DistanceSensorStatus("ok", f"{d:.3f} mm")


@dataclass
class FakeStation:
    """A fake robot, camera and table wired through one ``Scene``, as ``StationDevices``."""

    robot: FakeRobot = field(default_factory=FakeRobot)
    table: FakeTable = field(default_factory=FakeTable)
    camera: FakeCamera | None = None
    broker: PromptBroker = field(default_factory=PromptBroker)
    distance_sensor: FakeDistanceSensor | None = None

    def __post_init__(self) -> None:
        if self.camera is None:
            self.camera = FakeCamera(
                scene=Scene(robot=self.robot, table=self.table, reference_deg=tuple(self.robot.joints))
            )

    @property
    def cam(self) -> FakeCamera:
        """The fake camera (built in ``__post_init__`` when not given)."""
        assert self.camera is not None
        return self.camera

    def devices(self) -> StationDevices:
        assert self.camera is not None
        config = StationConfig(
            name="fake",
            robot=RobotConfig(driver="fake", reference_joints_deg=tuple(self.robot.joints)),
            camera=CameraConfig(driver="fake"),
            table=TableConfig(driver="fake", prompts="api"),
            distance_sensor=None if self.distance_sensor is None else DistanceSensorConfig(driver="fake"),
        )
        return StationDevices(
            config=config,
            camera=self.camera,
            broker=self.broker,
            robot=self.robot,
            table=self.table,
            distance_sensor=self.distance_sensor,
        )


__all__ = ["FakeCamera", "FakeDistanceSensor", "FakeRobot", "FakeStation", "FakeTable", "Scene", "draw_cross"]
