"""On the station's real camera (``pytest --hardware``): ``$STATION_CONFIG`` names the configuration whose
[camera] is opened (driver and options) and whose camera model, when set, must hold for the camera's
frames. The checks a session relies on: new frames of one size and format, ids that never repeat, a
status that matches the frames, a sensor that is not frozen."""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np
import pytest

from station import config
from station.camera_model import check_image_size, read_camera_model
from station.devices import PIXEL_FORMATS, Camera

pytestmark = [pytest.mark.hardware, pytest.mark.timeout(120)]


@pytest.fixture(scope="module")
def camera() -> Iterator[tuple[Camera, config.StationConfig]]:
    path = os.environ.get("STATION_CONFIG")
    if not path:
        pytest.skip("set STATION_CONFIG to the station configuration whose [camera] to open")
    station = config.load_config(path)
    cam: Camera = config.build("camera", station.camera.driver, **station.camera.options)
    cam.connect()
    try:
        yield cam, station
    finally:
        cam.close()


def test_frames_are_new_of_one_size_and_match_the_status(camera: tuple[Camera, config.StationConfig]) -> None:
    cam, _ = camera
    frames = cam.grab_many(10, timeout_s=5.0)
    ids = [f.frame_id for f in frames]
    assert ids == sorted(set(ids)), f"frame ids repeat or go back: {ids}"
    shapes = {f.image.shape for f in frames}
    assert len(shapes) == 1
    (shape,) = shapes
    status = cam.status()
    assert (status.height, status.width) == shape
    assert status.pixel_format in PIXEL_FORMATS
    assert frames[0].image.dtype == (np.uint8 if status.pixel_format == "Mono8" else np.uint16)
    stack = np.stack([f.image.astype(np.float64) for f in frames])
    assert float(stack.std(axis=0).mean()) > 0.0, "ten frames identical to the bit: is the sensor frozen?"


def test_the_configured_camera_model_holds_for_the_frames(
    camera: tuple[Camera, config.StationConfig],
) -> None:
    cam, station = camera
    if station.camera.camera_model is None:
        pytest.skip("no [camera] camera_model configured (run station run camera-calibration)")
    model = read_camera_model(station.camera.camera_model)
    height, width = cam.grab(timeout_s=5.0).image.shape[:2]
    check_image_size(model, width, height)  # raises ImageSizeError saying what to do
