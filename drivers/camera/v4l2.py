"""A V4L2 frame grabber (or USB camera) through OpenCV: ``cv2.VideoCapture(dev, cv2.CAP_V4L2)``.

Mono8 is V4L2's ``GREY`` and Mono16 its ``Y16``, read raw (OpenCV's RGB conversion off, which would
otherwise cut Y16 to 8 bits). ``grab`` drops frames that were already buffered when it was called:
it keeps reading until the kernel timestamp of a frame (CLOCK_MONOTONIC, OpenCV's ``CAP_PROP_POS_MSEC``)
is not older than the call; a device that reports no timestamps gets its buffered frames discarded
instead. A device that only ever hands back old frames ends in DeviceTimeoutError, never in a
reused frame.

The capture object is injectable (``capture_factory``), which is how this driver is tested: no V4L2
device can exist on the build machines.
"""

from __future__ import annotations

import logging
import math
import os
import stat
import threading
import time
from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any, Protocol

import cv2
import numpy as np

from station.devices import (
    CameraStatus,
    DeviceBusyError,
    DeviceConnectionError,
    DeviceError,
    DeviceIdentity,
    DeviceTimeoutError,
    Frame,
    FrameError,
    ImageArray,
    InvalidSettingError,
    NotSupportedError,
    grab_frames,
)

from ._frames import Layout, check_pixel_format, image_from_bytes

log = logging.getLogger(__name__)

FOURCC_OF = {"Mono8": "GREY", "Mono16": "Y16 "}
EXPOSURE_UNIT_US = 100.0
"""V4L2_CID_EXPOSURE_ABSOLUTE counts 100 µs units (V4L2 camera-control spec)."""
V4L2_EXPOSURE_MANUAL = 1
V4L2_MAJOR = 81
"""Linux's character-device major number of video4linux devices."""


class VideoCaptureLike(Protocol):
    """The part of ``cv2.VideoCapture`` this driver uses (an injected fake provides the same)."""

    def isOpened(self) -> bool: ...  # noqa: N802 - OpenCV's name

    def read(self) -> tuple[bool, Any]: ...

    def grab(self) -> bool: ...

    def set(self, prop: int, value: float) -> bool: ...

    def get(self, prop: int) -> float: ...

    def release(self) -> None: ...


CaptureFactory = Callable[[str | int], VideoCaptureLike]


def opencv_capture(device: str | int) -> VideoCaptureLike:
    """Open ``device`` (path or index) with OpenCV's V4L2 backend."""
    capture: VideoCaptureLike = cv2.VideoCapture(device, cv2.CAP_V4L2)
    return capture


def fourcc_code(text: str) -> int:
    """The V4L2 fourcc number of a four-character code (``"GREY"``)."""
    return int(cv2.VideoWriter.fourcc(*text))


def fourcc_text(code: float) -> str:
    """The four characters of a fourcc number, or ``"?"`` if it is not one."""
    value = int(code)
    if value <= 0:
        return "?"
    return "".join(chr((value >> (8 * i)) & 0xFF) for i in range(4))


def device_path(device: str | int) -> str:
    """``/dev/videoN`` for an index, the path itself otherwise."""
    return f"/dev/video{device}" if isinstance(device, int) else device


class V4L2Camera:
    """A V4L2 capture device as a station ``Camera`` (also ``ExposureAdjustable``, ``FrameRateAdjustable``).

    Parameters
    ----------
    device
        ``/dev/videoN`` path or index N.
    pixel_format
        ``"Mono8"`` (V4L2 GREY) or ``"Mono16"`` (V4L2 Y16).
    width, height
        Frame size to request; ``None`` keeps the device's current size.
    frame_rate_hz
        Frame rate to request; ``None`` keeps the device's.
    buffer_count
        Kernel buffers (fewer means fewer stale frames to drop).
    capture_factory
        Builds the capture object from ``device``; defaults to OpenCV's V4L2 backend.
    clock, monotonic
        Host time for frame timestamps, and the clock of the kernel's buffer timestamps.
    """

    def __init__(
        self,
        device: str | int = 0,
        *,
        pixel_format: str = "Mono8",
        width: int | None = None,
        height: int | None = None,
        frame_rate_hz: float | None = None,
        buffer_count: int = 1,
        capture_factory: CaptureFactory | None = None,
        clock: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        check_pixel_format(pixel_format)
        for name, value in (("width", width), ("height", height)):
            if value is not None and value < 1:
                raise ValueError(f"{name} must be a positive number of pixels or None, got {value}")
        if not 1 <= buffer_count <= 10:
            raise ValueError(f"buffer_count must be 1 to 10 (OpenCV's V4L2 limit), got {buffer_count}")
        self._device = device
        self._path = device_path(device)
        self._pixel_format = pixel_format
        self._size = (width, height)
        self._frame_rate_hz = frame_rate_hz
        self._buffer_count = buffer_count
        self._factory = capture_factory or opencv_capture
        self._clock = clock
        self._monotonic = monotonic
        self._cap: VideoCaptureLike | None = None
        self._layout = Layout(width or 0, height or 0, pixel_format)
        self._lock = threading.RLock()
        self._next_id = 1
        self._last_ts_ms: float | None = None
        self._read_timeout_ms: int | None = None
        self._exposure_us: float | None = None

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> None:
        """Open the device and set format, size, frame rate and buffers; errors say what to check."""
        with self._lock:
            if self._cap is not None:
                return
            if self._factory is opencv_capture and not os.path.exists(self._path):
                raise self._open_failure()  # say it before OpenCV prints its own warning on stderr
            cap = self._factory(self._device)
            if not cap.isOpened():
                cap.release()
                raise self._open_failure()
            try:
                self._configure(cap)
            except BaseException:
                cap.release()
                raise
            self._cap = cap
            self._last_ts_ms = None
            self._read_timeout_ms = None
            log.info("opened V4L2 %s: %s", self._path, self._layout.describe())

    def close(self) -> None:
        with self._lock:
            cap, self._cap = self._cap, None
            if cap is not None:
                cap.release()
                log.info("closed V4L2 %s", self._path)

    def identity(self) -> DeviceIdentity:
        """The device node, and the card name the kernel gives it (sysfs) where there is one."""
        node = os.path.basename(os.path.realpath(self._path))
        try:
            name = Path(f"/sys/class/video4linux/{node}/name").read_text(encoding="utf-8").strip() or None
        except OSError:
            name = None
        return DeviceIdentity(model=name, serial=None, port=self._path, firmware=None)

    def __enter__(self) -> V4L2Camera:
        self.connect()
        return self

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ Camera

    def grab(self, timeout_s: float = 2.0) -> Frame:
        """The first frame captured after this call; DeviceTimeoutError if none within ``timeout_s``."""
        if not (timeout_s > 0 and math.isfinite(timeout_s)):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
        with self._lock:
            cap = self._require_open()
            self._set_read_timeout(cap, timeout_s)
            started = self._monotonic()
            stale = 0
            if self._last_ts_ms == 0.0:  # no kernel timestamps: drop what the buffers may hold
                for _ in range(self._buffer_count):
                    if not cap.grab():
                        raise self._no_frame(cap, timeout_s)
            while True:
                ok, raw = cap.read()
                if not ok or raw is None:
                    raise self._no_frame(cap, timeout_s)
                ts_ms = float(cap.get(cv2.CAP_PROP_POS_MSEC))
                if ts_ms <= 0 or ts_ms >= started * 1000.0:
                    break
                stale += 1
                if self._monotonic() - started > timeout_s:
                    raise DeviceTimeoutError(
                        f"V4L2 {self._path}: only old frames within {timeout_s} s ({stale} dropped, the "
                        f"newest taken {started - ts_ms / 1000.0:.3f} s before the grab); the driver keeps "
                        "handing back buffered frames: reopen the device"
                    )
            if stale:
                log.debug("V4L2 %s: dropped %d buffered frame(s)", self._path, stale)
            image = self._to_mono(raw)
            self._last_ts_ms = max(ts_ms, 0.0)
            frame = Frame(image=image, timestamp_s=self._clock(), frame_id=self._next_id)
            self._next_id += 1
            return frame

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        return grab_frames(self.grab, count, average=average, timeout_s=timeout_s)

    def status(self) -> CameraStatus:
        with self._lock:
            cap = self._cap
            extra = {"device": self._path, "fourcc": FOURCC_OF[self._pixel_format].strip()}
            return CameraStatus(
                connected=cap is not None,
                model=f"V4L2 {self._path}",
                width=self._layout.width,
                height=self._layout.height,
                pixel_format=self._pixel_format,
                exposure_us=self._exposure_us,
                frame_rate_hz=float(cap.get(cv2.CAP_PROP_FPS)) if cap is not None else self._frame_rate_hz,
                extra=extra,
            )

    # ------------------------------------------------------------------ settings

    def exposure_us(self) -> float:
        """The exposure time (µs) from V4L2_CID_EXPOSURE_ABSOLUTE; NotSupportedError if it has none."""
        with self._lock:
            value = float(self._require_open().get(cv2.CAP_PROP_EXPOSURE))
            if value < 0:
                raise NotSupportedError(f"V4L2 {self._path} reports no exposure time (no exposure control)")
            return value * EXPOSURE_UNIT_US

    def set_exposure_us(self, exposure_us: float) -> float:
        """Switch to manual exposure and set it (rounded to 100 µs units); return what the device took."""
        if not (exposure_us > 0 and math.isfinite(exposure_us)):
            raise InvalidSettingError(f"exposure must be a positive number of µs, got {exposure_us!r}")
        units = max(1, round(exposure_us / EXPOSURE_UNIT_US))
        with self._lock:
            cap = self._require_open()
            if not cap.set(cv2.CAP_PROP_AUTO_EXPOSURE, V4L2_EXPOSURE_MANUAL):
                raise NotSupportedError(
                    f"V4L2 {self._path} has no manual exposure (v4l2-ctl -d {self._path} --list-ctrls)"
                )
            if not cap.set(cv2.CAP_PROP_EXPOSURE, units):
                raise InvalidSettingError(
                    f"V4L2 {self._path} refused exposure {exposure_us} µs ({units} x 100 µs); see its range "
                    f"with v4l2-ctl -d {self._path} --list-ctrls"
                )
            self._exposure_us = self.exposure_us()
            return self._exposure_us

    def frame_rate_hz(self) -> float:
        with self._lock:
            return float(self._require_open().get(cv2.CAP_PROP_FPS))

    def set_frame_rate_hz(self, frame_rate_hz: float) -> float:
        if not (frame_rate_hz > 0 and math.isfinite(frame_rate_hz)):
            raise InvalidSettingError(f"frame rate must be a positive number of Hz, got {frame_rate_hz!r}")
        with self._lock:
            cap = self._require_open()
            if not cap.set(cv2.CAP_PROP_FPS, frame_rate_hz):
                raise InvalidSettingError(
                    f"V4L2 {self._path} refused {frame_rate_hz} Hz; its rates are listed by "
                    f"v4l2-ctl -d {self._path} --list-formats-ext"
                )
            self._frame_rate_hz = float(cap.get(cv2.CAP_PROP_FPS))
            return self._frame_rate_hz

    # ------------------------------------------------------------------ internals

    def _require_open(self) -> VideoCaptureLike:
        if self._cap is None:
            raise DeviceConnectionError(f"V4L2 camera {self._path} is not open: call connect() first")
        return self._cap

    def _configure(self, cap: VideoCaptureLike) -> None:
        wanted = FOURCC_OF[self._pixel_format]
        cap.set(cv2.CAP_PROP_FOURCC, fourcc_code(wanted))
        got = fourcc_text(cap.get(cv2.CAP_PROP_FOURCC))
        if got != wanted:
            raise NotSupportedError(
                f"V4L2 {self._path} does not deliver {self._pixel_format} ({wanted.strip()}); it gave "
                f"{got!r}. Choose a pixel format it lists: v4l2-ctl -d {self._path} --list-formats-ext"
            )
        if not cap.set(cv2.CAP_PROP_CONVERT_RGB, 0) and self._pixel_format == "Mono16":
            raise NotSupportedError(
                f"V4L2 {self._path}: OpenCV would cut Mono16 to 8 bits (raw mode refused)"
            )
        width, height = self._size
        if width is not None and height is not None:
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, width)
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, height)
        got_size = (int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if any(w is not None and w != g for w, g in zip(self._size, got_size, strict=True)):
            raise NotSupportedError(
                f"V4L2 {self._path} gives {got_size[0]}x{got_size[1]}, not the {width}x{height} asked for; "
                f"choose a size it lists: v4l2-ctl -d {self._path} --list-formats-ext"
            )
        if got_size[0] < 1 or got_size[1] < 1:
            raise FrameError(
                f"V4L2 {self._path} reports a frame size of {got_size}; the device is not usable"
            )
        if not cap.set(cv2.CAP_PROP_BUFFERSIZE, self._buffer_count):
            log.warning("V4L2 %s: could not set %d buffer(s)", self._path, self._buffer_count)
        if self._frame_rate_hz is not None and not cap.set(cv2.CAP_PROP_FPS, self._frame_rate_hz):
            raise InvalidSettingError(f"V4L2 {self._path} refused {self._frame_rate_hz} Hz")
        self._layout = Layout(got_size[0], got_size[1], self._pixel_format)

    def _set_read_timeout(self, cap: VideoCaptureLike, timeout_s: float) -> None:
        ms = max(1, math.ceil(timeout_s * 1000))
        if ms != self._read_timeout_ms:
            if not cap.set(cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms):
                log.debug("V4L2 %s: backend keeps its own read timeout", self._path)
            self._read_timeout_ms = ms

    def _open_failure(self) -> DeviceConnectionError:
        path = self._path
        if not os.path.exists(path):
            return DeviceConnectionError(
                f"no V4L2 device at {path}: check that the camera or frame grabber is connected and its "
                "driver loaded (ls /dev/video*; v4l2-ctl --list-devices)"
            )
        info = os.stat(path)
        if not stat.S_ISCHR(info.st_mode) or os.major(info.st_rdev) != V4L2_MAJOR:
            return DeviceConnectionError(
                f"{path} is not a V4L2 video device; give the grabber's /dev/videoN path or its index "
                "(v4l2-ctl --list-devices)"
            )
        if not os.access(path, os.R_OK | os.W_OK):
            return DeviceConnectionError(
                f"no permission to open {path}: add the station's user to the 'video' group and log in again"
            )
        return DeviceBusyError(
            f"{path} exists but could not be opened for capture: another program probably holds it "
            f"(fuser -v {path}); close that program and retry"
        )

    def _no_frame(self, cap: VideoCaptureLike, timeout_s: float) -> DeviceError:
        if not cap.isOpened():
            self.close()
            return DeviceConnectionError(
                f"V4L2 {self._path} was lost while grabbing: check the cable, then open the camera again"
            )
        return DeviceTimeoutError(
            f"no frame from V4L2 {self._path} within {timeout_s} s: check the camera's video signal and "
            f"trigger; if no grab ever worked, another program may hold the device (fuser -v {self._path})"
        )

    def _to_mono(self, raw: Any) -> ImageArray:
        layout = self._layout
        source = f"V4L2 {self._path}"
        if not isinstance(raw, np.ndarray):
            raise FrameError(f"{source}: the capture returned {type(raw).__name__}, not an image")
        if raw.ndim == 2 and raw.shape == (layout.height, layout.width) and raw.dtype == layout.dtype:
            image: ImageArray = raw.copy()
        elif (
            raw.ndim == 3
            and raw.shape == (layout.height, layout.width, 3)
            and raw.dtype == np.uint8
            and layout.pixel_format == "Mono8"
        ):
            image = np.ascontiguousarray(raw[:, :, 0])  # GREY expanded to BGR: the channels are equal
        elif raw.ndim == 2 and raw.shape[0] == 1 and raw.dtype == np.uint8:
            image = image_from_bytes(raw.tobytes(), layout, source=source)  # raw buffer, one row of bytes
        else:
            raise FrameError(
                f"{source}: corrupt frame, expected {layout.describe()}, got shape {raw.shape} {raw.dtype} "
                f"({raw.nbytes} bytes)",
                expected_bytes=layout.nbytes,
                got_bytes=int(raw.nbytes),
            )
        image.setflags(write=False)
        return image
