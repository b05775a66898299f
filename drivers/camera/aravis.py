"""GenICam cameras (GigE Vision, USB3 Vision) through Aravis 0.8, via PyGObject.

``discover()`` lists the cameras Aravis sees (``_aravis_lib``: loading Aravis, discovery, buffers);
``AravisCamera(camera_id)`` opens one by device id (``"Fake_1"``, ``"Aravis-Fake-GV02"``), serial number or
IP address, in Mono8 or Mono16, with ROI, exposure, gain and frame rate. While open, the camera free-runs
into a pool of ``buffer_count`` buffers; ``grab`` returns the first frame whose transfer began after the
call (Aravis' host timestamp), so nothing buffered during a robot move is ever returned, and raises
``FrameError`` for an incomplete or mis-sized frame. ``close`` stops acquisition and releases the stream
before the camera (the other order aborts the process at exit); a finalizer does the same if ``close`` was
forgotten.

Aravis' in-process fake camera (``Fake_1``, enabled on demand) and its GigE Vision simulator
(``arv-fake-gv-camera-0.8``) are what the tests drive.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import weakref
from collections.abc import Callable
from types import ModuleType, TracebackType
from typing import Any, TypeVar

from station.devices import (
    CameraStatus,
    DeviceBusyError,
    DeviceConnectionError,
    DeviceError,
    DeviceIdentity,
    DeviceTimeoutError,
    Frame,
    FrameError,
    InvalidSettingError,
    NotSupportedError,
    Roi,
    grab_frames,
)

from ._aravis_lib import (
    ARAVIS_API,
    INSTALL_HINT,
    PIXEL_FORMAT_CODES,
    CameraInfo,
    aravis_available,
    discover,
    image_from_buffer,
    load_aravis,
)
from ._frames import Layout, check_pixel_format

log = logging.getLogger(__name__)


T = TypeVar("T")


class _Handles:
    """The Aravis objects of one open camera; released stream first, camera last."""

    def __init__(self, camera: Any) -> None:
        self.camera: Any = camera
        self.stream: Any = None

    def drop_stream(self, glib_error: type[Exception]) -> None:
        if self.camera is not None and self.stream is not None:
            try:
                self.camera.stop_acquisition()
            except glib_error as exc:  # the link may already be gone; releasing must go on
                log.warning("Aravis: stop_acquisition failed while closing: %s", exc)
        self.stream = None  # the last reference: the stream is finalised here, before the camera

    def release(self, glib_error: type[Exception]) -> None:
        self.drop_stream(glib_error)
        self.camera = None


def _release_at_finalize(handles: _Handles, glib_error: type[Exception]) -> None:
    if handles.camera is not None:
        log.warning("Aravis camera was not closed; releasing it (stream first)")
    handles.release(glib_error)


class AravisCamera:
    """A GenICam camera as a station ``Camera`` (also exposure, gain, ROI and frame rate adjustable).

    Parameters
    ----------
    camera_id
        Device id, serial number or IP address as ``discover()`` shows them; ``None`` opens the first
        camera found. Ids starting with ``Fake`` enable Aravis' in-process fake camera.
    pixel_format
        ``"Mono8"`` or ``"Mono16"``.
    roi, exposure_us, gain_db, frame_rate_hz
        Settings applied at ``open`` (``None`` keeps the camera's own).
    buffer_count
        Buffers in the stream's pool.
    clock
        Host wall clock (seconds) used when a camera gives no host timestamp.
    """

    def __init__(
        self,
        camera_id: str | None = None,
        *,
        pixel_format: str = "Mono8",
        roi: Roi | None = None,
        exposure_us: float | None = None,
        gain_db: float | None = None,
        frame_rate_hz: float | None = None,
        buffer_count: int = 4,
        clock: Callable[[], float] = time.time,
    ) -> None:
        check_pixel_format(pixel_format)
        if buffer_count < 2:
            raise ValueError(f"buffer_count must be at least 2 (one filling, one read), got {buffer_count}")
        self._camera_id = camera_id
        self._name = camera_id or "first GenICam camera"
        self._pixel_format = pixel_format
        self._initial = {"roi": roi, "exposure_us": exposure_us, "gain_db": gain_db, "fps": frame_rate_hz}
        self._buffer_count = buffer_count
        self._clock = clock
        self._lock = threading.RLock()
        self._handles: _Handles | None = None
        self._finalizer: weakref.finalize[Any, Any] | None = None
        self._glib_error: type[Exception] = Exception
        self._aravis: ModuleType | None = None
        self._layout = Layout(0, 0, pixel_format)
        self._model = ""
        self._identity = DeviceIdentity(model=None, serial=None, port=camera_id, firmware=None)
        self._next_id = 1
        self._last: tuple[int, int] | None = None

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> None:
        """Connect, take control, apply the settings and start free-running acquisition."""
        with self._lock:
            if self._handles is not None:
                return
            aravis, glib_error = load_aravis()
            self._aravis, self._glib_error = aravis, glib_error
            if self._camera_id is not None and self._camera_id.startswith("Fake"):
                aravis.enable_interface("Fake")
            try:
                camera = aravis.Camera.new(self._camera_id)
            except glib_error as exc:
                raise self._not_found(exc) from exc
            handles = _Handles(camera)
            self._finalizer = weakref.finalize(self, _release_at_finalize, handles, glib_error)
            self._handles = handles
            try:
                self._check_control(camera)
                self._model = f"{camera.get_vendor_name()} {camera.get_model_name()}".strip()
                self._identity = self._read_identity(camera)
                self._configure(camera)
                self._start(handles)
            except glib_error as exc:
                self.close()
                raise DeviceError(f"Aravis {self._name}: setting the camera up failed: {exc}") from exc
            except BaseException:
                self.close()
                raise
            log.info("opened Aravis %s (%s): %s", self._name, self._model, self._layout.describe())

    def close(self) -> None:
        """Stop acquisition, release the stream, then the camera; safe to call twice."""
        with self._lock:
            handles, self._handles = self._handles, None
            if handles is None:
                return
            handles.release(self._glib_error)
            if self._finalizer is not None:
                self._finalizer.detach()
                self._finalizer = None
            log.info("closed Aravis %s", self._name)

    def identity(self) -> DeviceIdentity:
        """Vendor and model, serial number, device id and firmware version (read at connect)."""
        return self._identity

    def _read_identity(self, camera: Any) -> DeviceIdentity:
        firmware: str | None = None
        for feature in ("DeviceFirmwareVersion", "DeviceVersion"):
            try:
                firmware = str(camera.get_string(feature)) or None
            except self._glib_error:
                continue
            if firmware:
                break
        return DeviceIdentity(
            model=self._model or None,
            serial=str(camera.get_device_serial_number() or "") or None,
            port=str(camera.get_device_id() or "") or self._camera_id,
            firmware=firmware,
        )

    def __enter__(self) -> AravisCamera:
        self.connect()
        return self

    def __exit__(self, *exc: type[BaseException] | BaseException | TracebackType | None) -> None:
        self.close()

    # ------------------------------------------------------------------ Camera

    def grab(self, timeout_s: float = 2.0) -> Frame:
        """The first frame whose transfer began after this call.

        DeviceTimeoutError if none arrives within ``timeout_s``; FrameError if it is incomplete or not
        the size and format the camera was set to.
        """
        if not (timeout_s > 0 and math.isfinite(timeout_s)):
            raise ValueError(f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
        with self._lock:
            handles = self._require_open()
            stream = handles.stream
            called_ns = time.time_ns() // 1000 * 1000  # Aravis stamps host time in whole µs
            deadline = time.monotonic() + timeout_s
            stale = 0
            if self._last is not None and self._last[1] == 0:  # no host timestamps: drop what is queued
                while (old := stream.try_pop_buffer()) is not None:
                    stream.push_buffer(old)
                    stale += 1
            while True:
                remaining_us = int((deadline - time.monotonic()) * 1e6)
                buffer = stream.timeout_pop_buffer(remaining_us) if remaining_us > 0 else None
                if buffer is None:
                    raise DeviceTimeoutError(
                        f"no frame from Aravis {self._name} within {timeout_s} s ({stale} old frame(s) "
                        "dropped): check the camera's power, cable or network, its trigger mode, and that "
                        "the exposure is shorter than the timeout"
                    )
                try:
                    arrived_ns = int(buffer.get_system_timestamp())
                    if 0 < arrived_ns < called_ns:
                        stale += 1
                        continue
                    frame = self._frame_from(buffer, arrived_ns)
                finally:
                    stream.push_buffer(buffer)
                if stale:
                    log.debug("Aravis %s: dropped %d buffered frame(s)", self._name, stale)
                return frame

    def grab_many(self, count: int, *, average: bool = False, timeout_s: float = 2.0) -> list[Frame]:
        return grab_frames(self.grab, count, average=average, timeout_s=timeout_s)

    def status(self) -> CameraStatus:
        with self._lock:
            if self._handles is None:
                return CameraStatus(
                    connected=False,
                    model=self._model or self._name,
                    width=self._layout.width,
                    height=self._layout.height,
                    pixel_format=self._pixel_format,
                )
            camera = self._handles.camera
            assert self._aravis is not None
            stats = self._aravis.Stream.get_statistics(self._handles.stream)  # GvStream shadows it
            extra = {
                "id": str(camera.get_device_id() or ""),
                "serial": str(camera.get_device_serial_number() or ""),
                "transport": "GigE Vision" if camera.is_gv_device() else "other",
                "frames_completed": str(stats.n_completed_buffers),
                "frames_failed": str(stats.n_failures),
                "buffer_underruns": str(stats.n_underruns),
            }
            return CameraStatus(
                connected=True,
                model=self._model,
                width=self._layout.width,
                height=self._layout.height,
                pixel_format=self._pixel_format,
                exposure_us=self._optional(camera, "get_exposure_time", "is_exposure_time_available"),
                gain_db=self._optional(camera, "get_gain", "is_gain_available"),
                frame_rate_hz=self._optional(camera, "get_frame_rate", "is_frame_rate_available"),
                extra=extra,
            )

    # ------------------------------------------------------------------ settings

    def exposure_us(self) -> float:
        camera = self._camera_with("exposure time", "is_exposure_time_available")
        return float(self._call(camera.get_exposure_time))

    def set_exposure_us(self, exposure_us: float) -> float:
        with self._lock:
            camera = self._camera_with("exposure time", "is_exposure_time_available")
            self._check_bounds("exposure", exposure_us, camera.get_exposure_time_bounds(), "µs")
            if camera.is_exposure_auto_available():
                self._call(camera.set_exposure_time_auto, self._aravis_auto_off())
            self._call(camera.set_exposure_time, float(exposure_us))
            return float(self._call(camera.get_exposure_time))

    def gain_db(self) -> float:
        camera = self._camera_with("gain", "is_gain_available")
        return float(self._call(camera.get_gain))

    def set_gain_db(self, gain_db: float) -> float:
        with self._lock:
            camera = self._camera_with("gain", "is_gain_available")
            self._check_bounds("gain", gain_db, camera.get_gain_bounds(), "dB")
            if camera.is_gain_auto_available():
                self._call(camera.set_gain_auto, self._aravis_auto_off())
            self._call(camera.set_gain, float(gain_db))
            return float(self._call(camera.get_gain))

    def frame_rate_hz(self) -> float:
        camera = self._camera_with("frame rate", "is_frame_rate_available")
        return float(self._call(camera.get_frame_rate))

    def set_frame_rate_hz(self, frame_rate_hz: float) -> float:
        with self._lock:
            camera = self._camera_with("frame rate", "is_frame_rate_available")
            self._check_bounds("frame rate", frame_rate_hz, camera.get_frame_rate_bounds(), "Hz")
            self._call(camera.set_frame_rate, float(frame_rate_hz))
            return float(self._call(camera.get_frame_rate))

    def roi(self) -> Roi:
        with self._lock:
            region = self._require_open().camera.get_region()
            return Roi(int(region.x), int(region.y), int(region.width), int(region.height))

    def set_roi(self, roi: Roi | None) -> Roi:
        """Read out ``roi`` (``None``: the whole sensor); acquisition restarts with a new buffer pool."""
        with self._lock:
            handles = self._require_open()
            handles.drop_stream(self._glib_error)
            try:
                self._apply_roi(handles.camera, roi)
            finally:
                self._start(handles)
            return self.roi()

    # ------------------------------------------------------------------ internals

    def _require_open(self) -> _Handles:
        if self._handles is None:
            raise DeviceConnectionError(f"Aravis camera {self._name} is not open: call connect() first")
        return self._handles

    def _camera_with(self, what: str, probe: str) -> Any:
        camera = self._require_open().camera
        if not getattr(camera, probe)():
            raise NotSupportedError(f"Aravis {self._name} ({self._model}) has no {what} control")
        return camera

    def _call(self, method: Callable[..., T], *args: Any) -> T:
        try:
            return method(*args)
        except self._glib_error as exc:
            raise DeviceError(f"Aravis {self._name}: {exc}") from exc

    def _optional(self, camera: Any, getter: str, probe: str) -> float | None:
        return float(self._call(getattr(camera, getter))) if getattr(camera, probe)() else None

    def _aravis_auto_off(self) -> Any:
        assert self._aravis is not None
        return self._aravis.Auto.OFF

    def _check_bounds(self, what: str, value: float, bounds: Any, unit: str) -> None:
        low, high = float(bounds.min), float(bounds.max)
        if not (math.isfinite(value) and low <= value <= high):
            raise InvalidSettingError(
                f"Aravis {self._name}: {what} {value} {unit} is outside the camera's range "
                f"{low:g} to {high:g} {unit}"
            )

    def _not_found(self, exc: Exception) -> DeviceConnectionError:
        try:
            seen = ", ".join(f"{c.id} ({c.address})" for c in discover()) or "none"
        except DeviceError:
            seen = "unknown"
        return DeviceConnectionError(
            f"cannot open GenICam camera {self._name}: {exc}. Cameras seen now: {seen}. Check the camera's "
            "power and cable, that it and this PC are on one subnet (GigE), and try arv-tool-0.8"
        )

    def _check_control(self, camera: Any) -> None:
        if camera.is_gv_device() and not camera.get_device().is_controller():
            raise DeviceBusyError(
                f"Aravis {self._name}: another application controls this camera (a viewer, another "
                "station?); close it and retry (a crashed one lets go after about 3 s)"
            )

    def _configure(self, camera: Any) -> None:
        formats = list(camera.dup_available_pixel_formats_as_strings() or [])
        if self._pixel_format not in formats:
            raise NotSupportedError(
                f"Aravis {self._name} does not offer {self._pixel_format}; it offers {', '.join(formats)}"
            )
        camera.set_pixel_format_from_string(self._pixel_format)
        if camera.dup_available_triggers():
            camera.clear_triggers()  # free-running: grab picks the first frame after the call
        assert self._aravis is not None
        camera.set_acquisition_mode(self._aravis.AcquisitionMode.CONTINUOUS)
        roi = self._initial["roi"]
        if isinstance(roi, Roi):
            self._apply_roi(camera, roi)
        for value, setter in (
            (self._initial["exposure_us"], self.set_exposure_us),
            (self._initial["gain_db"], self.set_gain_db),
            (self._initial["fps"], self.set_frame_rate_hz),
        ):
            if isinstance(value, int | float):
                setter(float(value))

    def _apply_roi(self, camera: Any, roi: Roi | None) -> None:
        sensor = camera.get_sensor_size()
        sensor_w, sensor_h = int(sensor.width), int(sensor.height)
        if roi is None:
            roi = Roi(0, 0, sensor_w, sensor_h)
        if roi.width < 1 or roi.height < 1 or roi.x < 0 or roi.y < 0:
            raise InvalidSettingError(f"Aravis {self._name}: ROI {roi} needs offsets >= 0 and sizes >= 1")
        if roi.x + roi.width > sensor_w or roi.y + roi.height > sensor_h:
            raise InvalidSettingError(
                f"Aravis {self._name}: ROI {roi} does not fit on the {sensor_w}x{sensor_h} sensor"
            )
        for what, value, step in (
            ("width", roi.width, camera.get_width_increment()),
            ("height", roi.height, camera.get_height_increment()),
        ):
            if step > 1 and value % step:
                raise InvalidSettingError(
                    f"Aravis {self._name}: ROI {what} must be a multiple of {step}, got {value}"
                )
        camera.set_region(roi.x, roi.y, roi.width, roi.height)

    def _start(self, handles: _Handles) -> None:
        camera = handles.camera
        region = camera.get_region()
        self._layout = Layout(int(region.width), int(region.height), self._pixel_format)
        payload = int(camera.get_payload())
        assert self._aravis is not None
        stream = camera.create_stream(None, None)
        if stream is None:
            raise DeviceConnectionError(f"Aravis {self._name}: no stream could be created")
        for _ in range(self._buffer_count):
            stream.push_buffer(self._aravis.Buffer.new_allocate(payload))
        handles.stream = stream
        camera.start_acquisition()
        self._last = None

    def _frame_from(self, buffer: Any, arrived_ns: int) -> Frame:
        assert self._aravis is not None
        source = f"Aravis {self._name}"
        image = image_from_buffer(buffer, self._layout, aravis=self._aravis, source=source)
        device_id = int(buffer.get_frame_id())
        key = (device_id, arrived_ns)
        if arrived_ns == 0 and key == self._last:
            raise FrameError(f"{source}: the camera delivered frame {device_id} twice")
        self._last = key
        frame = Frame(
            image=image,
            timestamp_s=arrived_ns / 1e9 if arrived_ns > 0 else self._clock(),
            frame_id=self._next_id,
            device_frame_id=device_id,
        )
        self._next_id += 1
        return frame


__all__ = [
    "ARAVIS_API",
    "INSTALL_HINT",
    "PIXEL_FORMAT_CODES",
    "AravisCamera",
    "CameraInfo",
    "aravis_available",
    "discover",
    "image_from_buffer",
    "load_aravis",
]
