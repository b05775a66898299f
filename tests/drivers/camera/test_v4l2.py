"""The V4L2 driver's error paths and frame handling, over an injected capture object.

No V4L2 device can exist on the build machines (no kernel modules, no v4l2loopback), so everything
but "no such device" runs against ``FakeV4L2Capture``; that one also runs through real OpenCV.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from drivers.camera.v4l2 import V4L2_MAJOR, V4L2Camera, device_path, fourcc_code, fourcc_text
from station.devices import (
    DeviceBusyError,
    DeviceConnectionError,
    DeviceTimeoutError,
    ExposureAdjustable,
    FrameError,
    FrameRateAdjustable,
    GainAdjustable,
    InvalidSettingError,
    NotSupportedError,
    RoiSelectable,
)

from .fakes import FakeMonotonic, FakeV4L2Capture


class Device:
    """A fake device slot: the capture the driver gets, and how the driver was built."""

    def __init__(self, **capture_options: object) -> None:
        self.clock = FakeMonotonic()
        self.capture = FakeV4L2Capture(self.clock, **capture_options)  # type: ignore[arg-type]
        self.opened_with: list[str | int] = []

    def factory(self, device: str | int) -> FakeV4L2Capture:
        self.opened_with.append(device)
        return self.capture

    def camera(self, device: str | int = "/dev/video0", **options: object) -> V4L2Camera:
        return V4L2Camera(device, capture_factory=self.factory, monotonic=self.clock, **options)  # type: ignore[arg-type]


@pytest.fixture
def device() -> Device:
    return Device()


@pytest.fixture
def camera(device: Device) -> Iterator[V4L2Camera]:
    cam = device.camera()
    cam.connect()
    yield cam
    cam.close()


# ------------------------------------------------------------------ opening


def test_a_missing_device_path_says_what_to_check(tmp_path: Path) -> None:
    missing = tmp_path / "video9"
    cam = V4L2Camera(str(missing))  # the default (OpenCV) capture
    expected = rf"no V4L2 device at {missing}: .*v4l2-ctl --list-devices"
    with pytest.raises(DeviceConnectionError, match=expected):
        cam.connect()
    assert cam.status().connected is False


def test_a_missing_index_names_its_device_path() -> None:
    unopened = Device(opened=False)
    with pytest.raises(DeviceConnectionError, match="no V4L2 device at /dev/video57"):
        unopened.camera(57).connect()
    assert unopened.opened_with == [57]
    assert unopened.capture.released
    assert device_path(57) == "/dev/video57"


@pytest.mark.parametrize("kind", ["regular file", "other character device"])
def test_a_path_that_is_not_a_video_device_is_named(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "video0"
    if kind == "regular file":
        path.write_bytes(b"")
    else:
        path = Path("/dev/null")
    with pytest.raises(DeviceConnectionError, match="is not a V4L2 video device"):
        Device(opened=False).camera(str(path)).connect()


def test_a_video_device_that_does_not_open_is_reported_busy(tmp_path: Path) -> None:
    node = tmp_path / "video200"
    try:  # a video4linux node with no driver behind it
        os.mknod(node, stat.S_IFCHR | 0o600, os.makedev(V4L2_MAJOR, 200))
    except PermissionError:
        pytest.skip("making a device node needs root (CAP_MKNOD); CI runs as root")
    expected = rf"another program probably holds it \(fuser -v {node}\)"
    with pytest.raises(DeviceBusyError, match=expected):
        Device(opened=False).camera(str(node)).connect()


def test_an_unsupported_pixel_format_is_refused_and_the_device_released() -> None:
    grey_only = Device(fourccs=("GREY",))
    with pytest.raises(NotSupportedError, match=r"does not deliver Mono16 \(Y16\).*--list-formats-ext"):
        grey_only.camera(pixel_format="Mono16").connect()
    assert grey_only.capture.released


def test_an_unsupported_size_is_refused(device: Device) -> None:
    with pytest.raises(NotSupportedError, match="gives 64x48, not the 640x480 asked for"):
        device.camera(width=640, height=480).connect()
    assert device.capture.released


def test_a_supported_size_is_set(device: Device) -> None:
    with device.camera(width=32, height=24) as cam:
        assert cam.grab().image.shape == (24, 32)


def test_mono16_needs_raw_mode(device: Device) -> None:
    device.capture.refuse.add(cv2.CAP_PROP_CONVERT_RGB)
    with pytest.raises(NotSupportedError, match=r"cut Mono16 to 8 bits \(raw mode refused\)"):
        device.camera(pixel_format="Mono16").connect()


def test_open_requests_format_raw_mode_and_few_buffers(device: Device) -> None:
    with device.camera(buffer_count=2, frame_rate_hz=30.0):
        sets = {prop: value for name, prop, value in device.capture.calls if name == "set"}
    assert fourcc_text(sets[cv2.CAP_PROP_FOURCC]) == "GREY"
    assert sets[cv2.CAP_PROP_CONVERT_RGB] == 0
    assert sets[cv2.CAP_PROP_BUFFERSIZE] == 2
    assert sets[cv2.CAP_PROP_FPS] == 30.0


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"pixel_format": "YUYV"}, "pixel_format"),
        ({"width": 0}, "width"),
        ({"buffer_count": 11}, "buffer_count"),
    ],
)
def test_bad_options_are_refused_before_opening(options: dict[str, object], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        V4L2Camera(0, **options)  # type: ignore[arg-type]


# ------------------------------------------------------------------ grabbing


def _sequence(image: np.ndarray) -> int:
    return int(image[0, 0])


def test_frames_buffered_before_the_grab_are_dropped(camera: V4L2Camera, device: Device) -> None:
    camera.grab()
    device.capture.buffer_old_frames(3)  # e.g. captured while the robot was moving
    newest_old = device.capture.sequence
    frame = camera.grab()
    assert _sequence(frame.image) == newest_old + 1


def test_without_timestamps_the_buffers_are_discarded_first(device: Device) -> None:
    device.capture.timestamps = False
    with device.camera(buffer_count=2) as cam:
        cam.grab()
        device.capture.buffer_old_frames(2)
        newest_old = device.capture.sequence
        assert _sequence(cam.grab().image) == newest_old + 1


def test_a_device_that_hands_back_old_frames_times_out_instead_of_reusing_them(
    camera: V4L2Camera, device: Device
) -> None:
    camera.grab()
    device.capture.frozen = True
    with pytest.raises(DeviceTimeoutError, match="only old frames"):
        camera.grab(timeout_s=0.5)


def test_no_frame_is_a_timeout_that_says_what_to_check(camera: V4L2Camera, device: Device) -> None:
    device.capture.stalled = True
    with pytest.raises(DeviceTimeoutError, match=r"no frame from V4L2 /dev/video0 within 0.25 s: check"):
        camera.grab(timeout_s=0.25)
    assert ("set", cv2.CAP_PROP_READ_TIMEOUT_MSEC, 250) in device.capture.calls
    assert camera.status().connected is True


def test_a_lost_device_closes_the_camera(camera: V4L2Camera, device: Device) -> None:
    device.capture.lost = True
    with pytest.raises(DeviceConnectionError, match="was lost while grabbing"):
        camera.grab()
    assert camera.status().connected is False
    assert device.capture.released


def test_a_short_frame_is_reported_with_expected_and_got_bytes(camera: V4L2Camera, device: Device) -> None:
    device.capture.corrupt = True
    expected = r"expected 64x48 Mono8 \(3072 bytes\), got shape \(24, 64\)"
    with pytest.raises(FrameError, match=expected) as info:
        camera.grab()
    assert (info.value.expected_bytes, info.value.got_bytes) == (3072, 1536)


@pytest.mark.parametrize(("pixel_format", "layout"), [("Mono8", "row"), ("Mono16", "row"), ("Mono8", "bgr")])
def test_raw_and_converted_layouts_become_the_same_mono_image(
    device: Device, pixel_format: str, layout: str
) -> None:
    with device.camera(pixel_format=pixel_format) as cam:
        plain = cam.grab().image
        device.capture.layout = layout
        other = cam.grab().image
    assert other.dtype == plain.dtype
    assert other.shape == plain.shape
    np.testing.assert_array_equal(other[1:], plain[1:])  # row 0 carries the frame number


def test_frames_are_read_only(camera: V4L2Camera) -> None:
    assert not camera.grab().image.flags.writeable


@pytest.mark.parametrize("timeout_s", [0.0, -1.0, float("inf"), float("nan")])
def test_a_bad_timeout_is_refused(camera: V4L2Camera, timeout_s: float) -> None:
    with pytest.raises(ValueError, match="timeout_s"):
        camera.grab(timeout_s=timeout_s)


# ------------------------------------------------------------------ settings


def test_offers_exposure_and_frame_rate_but_not_gain_or_roi(camera: V4L2Camera) -> None:
    assert isinstance(camera, ExposureAdjustable)
    assert isinstance(camera, FrameRateAdjustable)
    assert not isinstance(camera, GainAdjustable)
    assert not isinstance(camera, RoiSelectable)


def test_exposure_is_set_manually_in_100_us_units(camera: V4L2Camera, device: Device) -> None:
    assert camera.set_exposure_us(2540.0) == pytest.approx(2500.0)
    assert ("set", cv2.CAP_PROP_AUTO_EXPOSURE, 1) in device.capture.calls
    assert ("set", cv2.CAP_PROP_EXPOSURE, 25) in device.capture.calls
    assert camera.status().exposure_us == pytest.approx(2500.0)


def test_a_device_without_exposure_control_says_so(camera: V4L2Camera, device: Device) -> None:
    device.capture.refuse.add(cv2.CAP_PROP_AUTO_EXPOSURE)
    with pytest.raises(NotSupportedError, match="no manual exposure"):
        camera.set_exposure_us(1000.0)
    with pytest.raises(NotSupportedError, match="reports no exposure time"):
        camera.exposure_us()


def test_exposure_and_frame_rate_must_be_positive(camera: V4L2Camera) -> None:
    with pytest.raises(InvalidSettingError, match="exposure"):
        camera.set_exposure_us(0.0)
    with pytest.raises(InvalidSettingError, match="frame rate"):
        camera.set_frame_rate_hz(-5.0)


def test_frame_rate_is_set_and_read_back(camera: V4L2Camera) -> None:
    assert camera.set_frame_rate_hz(15.0) == pytest.approx(15.0)
    assert camera.frame_rate_hz() == pytest.approx(15.0)


def test_fourcc_round_trips() -> None:
    assert fourcc_text(fourcc_code("Y16 ")) == "Y16 "
    assert fourcc_text(0) == "?"


def test_the_station_builds_it_by_name(device: Device) -> None:
    from station.config import build

    cam = build("camera", "v4l2", device=3, capture_factory=device.factory, monotonic=device.clock)
    assert isinstance(cam, V4L2Camera)
    with cam:
        assert cam.status().extra["device"] == "/dev/video3"
