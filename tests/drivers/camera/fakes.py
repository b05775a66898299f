"""A V4L2 device as OpenCV's capture object presents it, for tests (no V4L2 device can exist here).

``FakeV4L2Capture`` answers ``set``/``get``/``read`` like ``cv2.VideoCapture`` with the V4L2 backend:
fourcc and size negotiation, raw mode, kernel timestamps (``CAP_PROP_POS_MSEC``, on the shared
``FakeMonotonic`` clock), a queue of already-buffered frames, and the failures a real grabber shows.
Every frame's first pixel row starts with its sequence number so tests can tell frames apart.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import cv2
import numpy as np

from drivers.camera.v4l2 import fourcc_code, fourcc_text


class FakeMonotonic:
    """The kernel's CLOCK_MONOTONIC as the driver and the fake device share it; ticks when read."""

    def __init__(self, start: float = 100.0, tick: float = 0.001) -> None:
        self.now = start
        self.tick = tick

    def __call__(self) -> float:
        self.now += self.tick
        return self.now


class FakeV4L2Capture:
    """Plays one V4L2 device. Attributes set by tests change its behaviour."""

    def __init__(
        self,
        clock: FakeMonotonic,
        *,
        width: int = 64,
        height: int = 48,
        fourccs: tuple[str, ...] = ("GREY", "Y16 "),
        sizes: tuple[tuple[int, int], ...] = ((64, 48), (32, 24)),
        opened: bool = True,
        frame_period_s: float = 0.02,
    ) -> None:
        self.clock = clock
        self.width, self.height = width, height
        self.fourccs = fourccs
        self.sizes = sizes
        self.opened = opened
        self.frame_period_s = frame_period_s
        self.fourcc = fourccs[0]
        self.convert_rgb = True
        self.timestamps = True  # the driver reports kernel timestamps
        self.layout = "2d"  # how frames come out: "2d", "bgr" (OpenCV's conversion), "row" (raw bytes)
        self.stalled = False  # read fails, device still open (no signal)
        self.lost = False  # read fails and the device is gone
        self.corrupt = False  # frames of the wrong size
        self.frozen = False  # hands back the same old buffer forever
        self.buffered: deque[tuple[int, float]] = deque()  # (sequence, timestamp) already captured
        self.sequence = 0
        self.last_ts_ms = 0.0
        self.released = False
        self.properties: dict[int, float] = {}
        self.refuse: set[int] = set()  # properties whose set() fails
        self.calls: list[tuple[str, int, float]] = []

    # ------------------------------------------------------------------ test helpers

    def buffer_old_frames(self, count: int) -> None:
        """Frames captured before now, waiting in the kernel queue (what a robot move leaves behind)."""
        for _ in range(count):
            self.sequence += 1
            self.buffered.append((self.sequence, self.clock.now - 0.5))

    # ------------------------------------------------------------------ cv2.VideoCapture

    def isOpened(self) -> bool:  # noqa: N802 - OpenCV's name
        return self.opened and not self.lost and not self.released

    def release(self) -> None:
        self.released = True

    def set(self, prop: int, value: float) -> bool:
        self.calls.append(("set", prop, value))
        if prop in self.refuse or not self.isOpened():
            return False
        if prop == cv2.CAP_PROP_FOURCC:
            text = fourcc_text(value)
            if text in self.fourccs:
                self.fourcc = text
            return True  # OpenCV answers True and keeps the old format: the driver must read back
        if prop == cv2.CAP_PROP_CONVERT_RGB:
            self.convert_rgb = bool(value)
            return True
        if prop == cv2.CAP_PROP_FRAME_WIDTH:
            self.properties[prop] = value
            return True
        if prop == cv2.CAP_PROP_FRAME_HEIGHT:
            wanted = (int(self.properties.get(cv2.CAP_PROP_FRAME_WIDTH, self.width)), int(value))
            if wanted in self.sizes:
                self.width, self.height = wanted
            return True
        self.properties[prop] = value
        return True

    def get(self, prop: int) -> float:
        if prop == cv2.CAP_PROP_FOURCC:
            return float(fourcc_code(self.fourcc))
        if prop == cv2.CAP_PROP_FRAME_WIDTH:
            return float(self.width)
        if prop == cv2.CAP_PROP_FRAME_HEIGHT:
            return float(self.height)
        if prop == cv2.CAP_PROP_POS_MSEC:
            return self.last_ts_ms if self.timestamps else 0.0
        if prop == cv2.CAP_PROP_FPS:
            return float(self.properties.get(prop, 1.0 / self.frame_period_s))
        return float(self.properties.get(prop, -1.0))

    def grab(self) -> bool:
        return self._next() is not None

    def read(self) -> tuple[bool, Any]:
        taken = self._next()
        if taken is None:
            return False, None
        return True, self._render(taken)

    # ------------------------------------------------------------------ internals

    def _next(self) -> int | None:
        if not self.isOpened() or self.stalled:
            if self.lost:
                self.opened = False
            return None
        if self.frozen and self.last_ts_ms:
            self.clock.now += self.frame_period_s
            return self.sequence
        if self.buffered:
            sequence, ts = self.buffered.popleft()
        else:
            self.clock.now += self.frame_period_s
            self.sequence += 1
            sequence, ts = self.sequence, self.clock.now
        self.last_ts_ms = ts * 1000.0
        return sequence

    def _render(self, sequence: int) -> Any:
        mono16 = self.fourcc.strip() == "Y16"
        dtype = np.uint16 if mono16 else np.uint8
        ramp = np.add.outer(np.arange(self.height), np.arange(self.width)) * (257 if mono16 else 1)
        image = (ramp % (65536 if mono16 else 256)).astype(dtype)
        image[0, 0] = sequence
        if self.corrupt:
            return image[: self.height // 2]
        if self.layout == "row":
            raw = image.astype("<u2" if mono16 else np.uint8).tobytes()
            return np.frombuffer(raw, np.uint8).reshape(1, -1)
        if self.layout == "bgr":
            return np.repeat(image[:, :, None], 3, axis=2)
        return image
