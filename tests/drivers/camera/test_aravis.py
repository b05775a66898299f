"""The Aravis driver against Aravis' own fake cameras: discovery, settings, ROI, errors, clean shutdown.

``Fake_1`` runs in this process; the GigE Vision simulator is a separate process on 127.0.0.1 (see
``gv_simulator.py``). Under ``CI=true`` a missing Aravis fails these tests instead of skipping them.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from drivers.camera._frames import Layout
from drivers.camera.aravis import AravisCamera, discover, image_from_buffer, load_aravis
from station.devices import (
    DeviceBusyError,
    DeviceConnectionError,
    ExposureAdjustable,
    FrameError,
    FrameRateAdjustable,
    GainAdjustable,
    InvalidSettingError,
    Roi,
    RoiSelectable,
)

from .conftest import require_aravis
from .gv_simulator import ADDRESS, DEVICE_ID, SERIAL

# The GigE Vision simulator keeps time (heartbeats, packet timeouts) and misses it when starved of CPU:
# `make test` runs these tests alone, after the parallel ones (marker ``gige``).
pytestmark = pytest.mark.gige


@pytest.fixture
def aravis() -> Any:
    require_aravis()
    module, _ = load_aravis()
    return module


@pytest.fixture
def fake(aravis: Any) -> Iterator[AravisCamera]:
    cam = AravisCamera("Fake_1", roi=Roi(0, 0, 64, 48), frame_rate_hz=100.0)
    cam.connect()
    yield cam
    cam.close()


def test_discovery_lists_the_in_process_fake_when_asked(aravis: Any) -> None:
    found = {c.id: c for c in discover(include_fake=True)}
    assert "Fake_1" in found
    fake = found["Fake_1"]
    assert (fake.vendor, fake.model, fake.protocol) == ("Aravis", "Fake", "Fake")


def test_discovery_finds_the_gige_simulator_on_loopback(gv_sim_pid: int) -> None:
    found = {c.id: c for c in discover()}
    assert DEVICE_ID in found
    assert found[DEVICE_ID].address == ADDRESS
    assert found[DEVICE_ID].protocol == "GigEVision"


@pytest.mark.parametrize("name", [ADDRESS, DEVICE_ID])
def test_opens_the_gige_simulator_by_address_or_id(gv_sim_pid: int, name: str) -> None:
    with AravisCamera(name, roi=Roi(0, 0, 32, 16), frame_rate_hz=100.0) as cam:
        status = cam.status()
        assert status.extra["serial"] == SERIAL
        assert status.extra["transport"] == "GigE Vision"
        assert cam.grab().image.shape == (16, 32)


def test_a_second_client_of_a_gige_camera_is_told_it_is_busy(gv_sim_pid: int) -> None:
    with AravisCamera(ADDRESS, roi=Roi(0, 0, 32, 16)):
        second = AravisCamera(ADDRESS)
        with pytest.raises(DeviceBusyError, match="another application controls this camera"):
            second.connect()  # Aravis tries to take control for about 2.5 s before giving up
        assert second.status().connected is False


def test_an_unknown_camera_is_named_with_what_was_seen(aravis: Any) -> None:
    with pytest.raises(DeviceConnectionError, match=r"cannot open GenICam camera no-such-camera.*seen now"):
        AravisCamera("no-such-camera").connect()


def test_offers_exposure_gain_roi_and_frame_rate(fake: AravisCamera) -> None:
    for ability in (ExposureAdjustable, GainAdjustable, RoiSelectable, FrameRateAdjustable):
        assert isinstance(fake, ability)


def test_settings_are_applied_and_read_back(fake: AravisCamera) -> None:
    assert fake.set_exposure_us(2500.0) == pytest.approx(2500.0)
    assert fake.set_gain_db(3.0) == pytest.approx(3.0)
    assert fake.set_frame_rate_hz(50.0) == pytest.approx(50.0)
    status = fake.status()
    assert (status.exposure_us, status.gain_db, status.frame_rate_hz) == (
        pytest.approx(2500.0),
        pytest.approx(3.0),
        pytest.approx(50.0),
    )


@pytest.mark.parametrize(
    ("setting", "value", "match"),
    [
        ("set_exposure_us", 1.0, r"exposure 1.0 µs is outside the camera's range 10 to"),
        ("set_gain_db", 11.0, r"gain 11.0 dB is outside the camera's range 0 to 10 dB"),
        ("set_frame_rate_hz", float("nan"), "frame rate nan Hz is outside"),
    ],
)
def test_settings_out_of_range_are_refused_and_nothing_changes(
    fake: AravisCamera, setting: str, value: float, match: str
) -> None:
    def settings() -> tuple[float | None, ...]:
        status = fake.status()
        return (status.exposure_us, status.gain_db, status.frame_rate_hz)

    before = settings()
    with pytest.raises(InvalidSettingError, match=match):
        getattr(fake, setting)(value)
    assert settings() == before


def test_roi_changes_the_frame_and_restarts_the_stream(fake: AravisCamera) -> None:
    assert fake.roi() == Roi(0, 0, 64, 48)
    assert fake.set_roi(Roi(16, 8, 32, 24)) == Roi(16, 8, 32, 24)
    frame = fake.grab()
    assert frame.image.shape == (24, 32)
    assert fake.status().width == 32
    full = fake.set_roi(None)
    assert (full.x, full.y) == (0, 0)
    assert fake.grab().image.shape == (full.height, full.width)


@pytest.mark.parametrize(
    ("roi", "match"),
    [(Roi(2040, 0, 16, 16), "does not fit"), (Roi(0, 0, 0, 16), "sizes >= 1"), (Roi(-1, 0, 8, 8), "offsets")],
)
def test_an_impossible_roi_is_refused_and_the_camera_keeps_going(
    fake: AravisCamera, roi: Roi, match: str
) -> None:
    with pytest.raises(InvalidSettingError, match=match):
        fake.set_roi(roi)
    assert fake.roi() == Roi(0, 0, 64, 48)
    assert fake.grab().image.shape == (48, 64)


def test_mono16_frames_keep_their_16_bits(aravis: Any) -> None:
    with AravisCamera("Fake_1", pixel_format="Mono16", roi=Roi(0, 0, 64, 48), frame_rate_hz=100.0) as cam:
        image = cam.grab().image
    assert image.dtype == np.uint16
    assert int(image.max()) > 255


def test_frames_are_read_only_copies(fake: AravisCamera) -> None:
    first = fake.grab()
    kept = first.image.copy()
    fake.grab_many(8)  # every buffer of the pool has been refilled since
    assert not first.image.flags.writeable
    np.testing.assert_array_equal(first.image, kept)


def test_device_frame_ids_are_reported(fake: AravisCamera) -> None:
    frames = fake.grab_many(2)
    assert all(f.device_frame_id is not None for f in frames)


def test_rejects_an_unsupported_pixel_format_or_pool() -> None:
    with pytest.raises(ValueError, match="Mono8, Mono16"):
        AravisCamera("Fake_1", pixel_format="RGB8")
    with pytest.raises(ValueError, match="buffer_count"):
        AravisCamera("Fake_1", buffer_count=1)


def test_a_forgotten_camera_is_released_stream_first(aravis: Any, caplog: pytest.LogCaptureFixture) -> None:
    cam = AravisCamera("Fake_1", roi=Roi(0, 0, 32, 16), frame_rate_hz=100.0)
    cam.connect()
    cam.grab()
    del cam
    gc.collect()
    assert "was not closed; releasing it (stream first)" in caplog.text


class StubBuffer:
    """An Aravis buffer as a camera may deliver it when something went wrong."""

    def __init__(
        self, aravis: Any, *, status: str = "SUCCESS", size: tuple[int, int] = (4, 2), data: bytes = b""
    ) -> None:
        self._aravis = aravis
        self._status = getattr(aravis.BufferStatus, status)
        self._size = size
        self._data = data or bytes(size[0] * size[1])

    def get_status(self) -> Any:
        return self._status

    def get_payload_type(self) -> Any:
        return self._aravis.BufferPayloadType.IMAGE

    def get_image_pixel_format(self) -> int:
        return 0x01080001

    def get_image_width(self) -> int:
        return self._size[0]

    def get_image_height(self) -> int:
        return self._size[1]

    def get_image_data(self) -> bytes:
        return self._data


@pytest.mark.parametrize(
    ("buffer_args", "match", "expected_got"),
    [
        ({"status": "MISSING_PACKETS"}, "incomplete frame \\(missing-packets\\)", None),
        ({"status": "TIMEOUT"}, "incomplete frame \\(timeout\\)", None),
        ({"size": (4, 3)}, "frame is 4x3 .* set to 4x2 Mono8", None),
        ({"data": b"\x00" * 5}, "expected 4x2 Mono8 \\(8 bytes\\), got 5 bytes", (8, 5)),
    ],
)
def test_corrupt_buffers_raise_frame_errors(
    aravis: Any, buffer_args: dict[str, Any], match: str, expected_got: tuple[int, int] | None
) -> None:
    with pytest.raises(FrameError, match=match) as info:
        image_from_buffer(
            StubBuffer(aravis, **buffer_args), Layout(4, 2, "Mono8"), aravis=aravis, source="cam"
        )
    if expected_got is not None:
        assert (info.value.expected_bytes, info.value.got_bytes) == expected_got


def test_the_station_builds_it_by_name(aravis: Any) -> None:
    from station.config import build

    cam = build("camera", "aravis", camera_id="Fake_1", roi=Roi(0, 0, 16, 8))
    assert isinstance(cam, AravisCamera)
    with cam:
        assert cam.grab().image.shape == (8, 16)
