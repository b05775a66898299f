"""The simulated camera on the flange: renders what it sees in the simulated world.

A sibling of the real drivers (``drivers/camera``): it satisfies ``station.devices.Camera`` and the
exposure, ROI and frame-rate protocols. Frames are rendered when grabbed, at most one per frame period
(free-running sensor: a grab waits for the next frame slot); noise is new in every frame, the artifact's
features stay on the artifact.
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from collections.abc import Callable

import numpy as np

from sim.world import World
from station.devices import (
    Camera,
    CameraStatus,
    DeviceConnectionError,
    DeviceIdentity,
    DeviceTimeoutError,
    Frame,
    InvalidSettingError,
    Roi,
    grab_frames,
)

log = logging.getLogger(__name__)

NOMINAL_EXPOSURE_US = 10_000.0


class SimCamera:
    """A 640x480 Mono8 camera looking at the simulated world.

    Parameters
    ----------
    world
        The simulated station the camera belongs to.
    seed
        Seed of the frame-to-frame noise.
    frame_rate_hz
        Free-running rate; 0 renders a frame as soon as one is asked for (tests).
    clock, sleep
        Injected time source and sleep (tests run without waiting).
    """

    model = "station-sim-camera"

    def __init__(
        self,
        world: World,
        *,
        seed: int = 0,
        frame_rate_hz: float = 30.0,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
    ) -> None:
        self.world = world
        self._rng = np.random.default_rng(seed)
        self._seed = seed
        self._clock = clock
        self._sleep = sleep
        self._lock = threading.Lock()
        self._open = False
        self._ids = itertools.count(1)
        self._exposure_us = NOMINAL_EXPOSURE_US
        self._frame_rate_hz = 0.0
        if frame_rate_hz:
            self.set_frame_rate_hz(frame_rate_hz)
        w, h = world.spec.camera.width, world.spec.camera.height
        self._sensor = Roi(0, 0, w, h)
        self._roi = self._sensor
        self._next_slot = 0.0
        self.before_grab: Callable[[], None] | None = None
        """Called before each frame is rendered (a micrometer follower waits there for the world to
        take the readings a person confirmed, as the real table has moved before the camera looks)."""

    # ------------------------------------------------------------------ Camera

    def connect(self) -> None:
        self._open = True

    def close(self) -> None:
        self._open = False

    def identity(self) -> DeviceIdentity:
        """The simulated camera, its world's preset and seed."""
        return DeviceIdentity(
            model=self.model, serial=f"sim-{self._seed}", port="in-process", firmware=self.world.spec.preset
        )

    def __enter__(self) -> SimCamera:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def grab(self, timeout_s: float = 2.0) -> Frame:
        if not self._open:
            raise DeviceConnectionError("the simulated camera is not open: call connect() first")
        if self.before_grab is not None:
            self.before_grab()
        with self._lock:
            if self._frame_rate_hz > 0:
                now = self._clock()
                wait = self._next_slot - now
                if wait > timeout_s:
                    raise DeviceTimeoutError(f"no frame within {timeout_s} s at {self._frame_rate_hz} Hz")
                if wait > 0:
                    self._sleep(wait)
                self._next_slot = max(now, self._next_slot) + 1.0 / self._frame_rate_hz
            image, _ = self.world.render(self._rng, exposure=self._exposure_us / NOMINAL_EXPOSURE_US)
            r = self._roi
            crop = np.ascontiguousarray(image[r.y : r.y + r.height, r.x : r.x + r.width])
            return Frame(image=crop, timestamp_s=time.time(), frame_id=next(self._ids))

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        return grab_frames(self.grab, count, average=average, timeout_s=timeout_s)

    def status(self) -> CameraStatus:
        return CameraStatus(
            connected=self._open,
            model=self.model,
            width=self._roi.width,
            height=self._roi.height,
            pixel_format="Mono8",
            exposure_us=self._exposure_us,
            gain_db=None,
            frame_rate_hz=self._frame_rate_hz or None,
            extra={"preset": self.world.spec.preset},
        )

    # ------------------------------------------------------------------ settings

    def exposure_us(self) -> float:
        return self._exposure_us

    def set_exposure_us(self, exposure_us: float) -> float:
        if not 10.0 <= exposure_us <= 1_000_000.0:
            raise InvalidSettingError(f"exposure {exposure_us} us is outside 10-1000000 us")
        self._exposure_us = float(exposure_us)
        return self._exposure_us

    def roi(self) -> Roi:
        return self._roi

    def set_roi(self, roi: Roi | None) -> Roi:
        s = self._sensor
        if roi is None:
            self._roi = s
            return s
        if (
            roi.width < 1
            or roi.height < 1
            or roi.x < 0
            or roi.y < 0
            or roi.x + roi.width > s.width
            or (roi.y + roi.height > s.height)
        ):
            raise InvalidSettingError(f"ROI {roi} does not fit the {s.width}x{s.height} sensor")
        self._roi = roi
        return roi

    def frame_rate_hz(self) -> float:
        return self._frame_rate_hz

    def set_frame_rate_hz(self, frame_rate_hz: float) -> float:
        if not 0.1 <= frame_rate_hz <= 1000.0:
            raise InvalidSettingError(f"frame rate {frame_rate_hz} Hz is outside 0.1-1000 Hz")
        self._frame_rate_hz = float(frame_rate_hz)
        return self._frame_rate_hz


def open_sim_camera(*, world: World | None = None, seed: int = 0, frame_rate_hz: float = 30.0) -> Camera:
    """Device factory (``camera.sim``): an unconnected simulated camera, in a fresh world unless given one."""
    return SimCamera(world or World(), seed=seed, frame_rate_hz=frame_rate_hz)
