"""The Camera contract, run against every implementation.

Cases: Aravis' in-process fake camera (``Fake_1``), Aravis' GigE Vision simulator on 127.0.0.1 (a
separate process), and the V4L2 driver over an injected capture object (no V4L2 device can exist on
the build machines), and the simulated flange camera of ``sim/``. A new implementation joins by adding a
``Rig`` builder to ``RIGS``: how to make an unopened camera (of ``size``, in one of ``pixel_formats``),
and how to make it stop delivering frames.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass, field

import numpy as np
import pytest

from drivers.camera.aravis import AravisCamera
from drivers.camera.v4l2 import V4L2Camera
from sim.camera import SimCamera
from sim.world import World
from station.devices import Camera, DeviceConnectionError, DeviceTimeoutError, Roi

from .conftest import require_aravis
from .fakes import FakeMonotonic, FakeV4L2Capture
from .gv_simulator import ADDRESS, GvSimulator

# The GigE Vision simulator keeps time (heartbeats, packet timeouts) and misses it when starved of CPU:
# `make test` runs these tests alone, after the parallel ones (marker ``gige``).
pytestmark = pytest.mark.gige

ROI = Roi(0, 0, 64, 48)
FAST_HZ = 100.0


def _no_buffers(cam: Camera) -> None:
    """A camera that renders each frame when asked holds none nobody asked for."""


@dataclass
class Rig:
    """One implementation under test: ``make(pixel_format)`` gives an unopened camera of ``size``;
    ``pile_up(camera)`` returns once frames nobody asked for wait in its buffers."""

    make: Callable[[str], Camera]
    stall: Callable[[Camera], AbstractContextManager[None]]
    size: tuple[int, int] = (ROI.width, ROI.height)
    pixel_formats: tuple[str, ...] = ("Mono8", "Mono16")
    made: list[Camera] = field(default_factory=list)
    pile_up: Callable[[Camera], None] = _no_buffers

    def camera(self, pixel_format: str = "Mono8") -> Camera:
        cam = self.make(pixel_format)
        self.made.append(cam)
        return cam


def _aravis_frames_arrive(cam: Camera, count: int = 3) -> None:
    """Wait until ``count`` more frames have arrived in the stream (its own completed-buffer count)."""
    start = int(cam.status().extra["frames_completed"])
    deadline = time.monotonic() + 5.0
    while int(cam.status().extra["frames_completed"]) < start + count:
        assert time.monotonic() < deadline, f"no {count} frames within 5 s at {FAST_HZ} Hz"
        time.sleep(0.002)


def _aravis_fake_rig(request: pytest.FixtureRequest) -> Rig:
    require_aravis()

    @contextlib.contextmanager
    def stall(cam: Camera) -> Iterator[None]:
        assert isinstance(cam, AravisCamera)
        # The fake ignores triggers: a slow rate is its only pause. It times frames on multiples of
        # the period, so the first frame after the change may come early; the second is on the new
        # beat, and the next one half a second after it.
        cam.set_frame_rate_hz(2.0)
        cam.grab_many(2, timeout_s=5.0)
        yield

    def make(pixel_format: str) -> Camera:
        return AravisCamera("Fake_1", pixel_format=pixel_format, roi=ROI, frame_rate_hz=FAST_HZ)

    return Rig(make, stall, pile_up=_aravis_frames_arrive)


def _aravis_gv_rig(request: pytest.FixtureRequest) -> Rig:
    pid: int = request.getfixturevalue("gv_sim_pid")

    @contextlib.contextmanager
    def stall(cam: Camera) -> Iterator[None]:
        GvSimulator.pause(pid)  # a frozen camera: nothing arrives, nothing answers
        try:
            yield
        finally:
            GvSimulator.resume(pid)

    def make(pixel_format: str) -> Camera:
        return AravisCamera(ADDRESS, pixel_format=pixel_format, roi=ROI, frame_rate_hz=FAST_HZ)

    return Rig(make, stall, pile_up=_aravis_frames_arrive)


def _v4l2_injected_rig(request: pytest.FixtureRequest) -> Rig:
    clock = FakeMonotonic()
    captures: list[FakeV4L2Capture] = []

    def capture_factory(device: str | int) -> FakeV4L2Capture:
        captures.append(FakeV4L2Capture(clock, width=ROI.width, height=ROI.height))
        return captures[-1]

    @contextlib.contextmanager
    def stall(cam: Camera) -> Iterator[None]:
        for capture in captures:
            capture.stalled = True
        yield

    def pile_up(cam: Camera) -> None:
        for capture in captures:
            capture.buffer_old_frames(3)  # captured before now, waiting in the kernel's queue

    def make(pixel_format: str) -> Camera:
        return V4L2Camera(
            "/dev/video0", pixel_format=pixel_format, capture_factory=capture_factory, monotonic=clock
        )

    return Rig(make, stall, pile_up=pile_up)


def _sim_rig(request: pytest.FixtureRequest) -> Rig:
    @contextlib.contextmanager
    def stall(cam: Camera) -> Iterator[None]:
        assert isinstance(cam, SimCamera)
        # a free-running sensor at 0.1 Hz: the next frame is 10 s away, beyond any grab's timeout
        cam.set_frame_rate_hz(0.1)
        cam.grab(timeout_s=1.0)
        yield

    def make(pixel_format: str) -> Camera:
        return SimCamera(World(), frame_rate_hz=FAST_HZ)

    return Rig(make, stall, size=(640, 480), pixel_formats=("Mono8",))


RIGS: dict[str, Callable[[pytest.FixtureRequest], Rig]] = {
    "sim": _sim_rig,
    "aravis-fake": _aravis_fake_rig,
    "aravis-gv": _aravis_gv_rig,
    "v4l2-injected": _v4l2_injected_rig,
}


@pytest.fixture(params=list(RIGS))
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    built = RIGS[request.param](request)
    yield built
    for cam in built.made:
        cam.close()


@pytest.fixture
def camera(rig: Rig) -> Camera:
    cam = rig.camera()
    cam.connect()
    return cam


def test_says_who_it_is_the_same_across_a_reconnect(rig: Rig) -> None:
    cam = rig.camera()
    assert isinstance(cam, Camera)
    cam.connect()
    identity = cam.identity()
    assert identity.model or identity.serial or identity.port  # something names the device
    assert cam.status().model  # and its status says which model answers
    cam.close()
    cam.connect()
    assert cam.identity() == identity


@pytest.mark.parametrize(("pixel_format", "dtype"), [("Mono8", np.uint8), ("Mono16", np.uint16)])
def test_grab_gives_a_2d_image_of_the_set_size_and_format(
    rig: Rig, pixel_format: str, dtype: type[np.generic]
) -> None:
    if pixel_format not in rig.pixel_formats:
        pytest.skip(f"this camera has no {pixel_format}")
    cam = rig.camera(pixel_format)
    cam.connect()
    frame = cam.grab()
    status = cam.status()
    assert frame.image.ndim == 2
    assert frame.image.dtype == dtype
    assert frame.image.shape == (status.height, status.width) == rig.size[::-1]
    assert status.pixel_format == pixel_format
    assert frame.averaged == 1


def test_frame_ids_never_repeat(camera: Camera) -> None:
    frames = [camera.grab(), *camera.grab_many(3), camera.grab()]
    ids = [f.frame_id for f in frames]
    assert ids == sorted(set(ids))
    stamps = [f.timestamp_s for f in frames]
    assert stamps == sorted(stamps)


def test_grab_never_returns_a_frame_from_before_the_call(rig: Rig, camera: Camera) -> None:
    camera.grab()
    rig.pile_up(camera)  # frames nobody asked for wait in the camera's buffers
    called = time.time_ns() // 1000 / 1e6
    frame = camera.grab()
    assert frame.timestamp_s >= called - 1e-6


def test_grab_many_gives_count_frames(camera: Camera) -> None:
    frames = camera.grab_many(3)
    assert len(frames) == 3
    assert len({f.frame_id for f in frames}) == 3


def test_grab_many_can_average(rig: Rig, camera: Camera) -> None:
    (frame,) = camera.grab_many(4, average=True)
    assert frame.averaged == 4
    assert frame.image.shape == rig.size[::-1]
    assert frame.image.dtype == np.uint8


@pytest.mark.parametrize("count", [0, -1, 1.5, True])
def test_grab_many_rejects_a_bad_count(camera: Camera, count: int) -> None:
    with pytest.raises(ValueError, match="count"):
        camera.grab_many(count)


def test_grab_times_out_when_no_frame_comes(rig: Rig, camera: Camera) -> None:
    with rig.stall(camera), pytest.raises(DeviceTimeoutError, match=r"no frame|only old frames"):
        camera.grab(timeout_s=0.05)


def test_grab_on_a_closed_camera_says_to_open_it(rig: Rig) -> None:
    cam = rig.camera()
    with pytest.raises(DeviceConnectionError, match="not open"):
        cam.grab()
    cam.connect()
    cam.close()
    with pytest.raises(DeviceConnectionError, match="not open"):
        cam.grab()


def test_open_twice_and_close_twice_are_harmless(rig: Rig) -> None:
    cam = rig.camera()
    cam.connect()
    cam.connect()
    cam.close()
    cam.close()
    assert cam.status().connected is False


def test_a_closed_camera_opens_again(rig: Rig) -> None:
    cam = rig.camera()
    cam.connect()
    first = cam.grab()
    cam.close()
    cam.connect()
    assert cam.status().connected is True
    assert cam.grab().frame_id > first.frame_id


def test_status_reports_the_device(rig: Rig, camera: Camera) -> None:
    status = camera.status()
    assert status.connected is True
    assert status.model
    assert (status.width, status.height) == rig.size
