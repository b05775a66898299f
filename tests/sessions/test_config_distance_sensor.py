"""A station configuration's ``[distance_sensor]`` section: driver, options and mount."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.distance_sensor import DistanceSensorTwin, HeadModel
from station.config import ConfigurationError, SensorMount, load_config, open_station
from station.devices import DistanceSensor

BASE = """
[camera]
driver = "v4l2"
options = { device = "/dev/video9" }
"""


def write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "station.toml"
    p.write_text(BASE + text)
    return p


def test_the_section_is_optional(tmp_path: Path) -> None:
    assert load_config(write(tmp_path, "")).distance_sensor is None


def test_driver_options_and_mount_are_read_and_the_sensor_is_built(tmp_path: Path) -> None:
    twin = DistanceSensorTwin(lambda: (np.eye(4), np.eye(4)), HeadModel()).start()
    try:
        config = load_config(
            write(
                tmp_path,
                f"""
[distance_sensor]
driver = "keyence_il"
options = {{ port = "{twin.port}", head = {{ model = "IL-065" }}, link = {{ reply_timeout_s = 0.3 }} }}
mount = {{ translation_mm = [30, 0, -2.5], rotation_deg = [0, 0, 90] }}
""",
            )
        )
        cfg = config.distance_sensor
        assert cfg is not None
        assert cfg.driver == "keyence_il"
        M = cfg.mount.matrix()
        np.testing.assert_allclose(M[:3, 3], [30.0, 0.0, -2.5])
        np.testing.assert_allclose(M[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
        assert config.snapshot()["distance_sensor"]["mount"]["rotation_deg"] == [0.0, 0.0, 90.0]
        devices = open_station(config)
        assert isinstance(devices.distance_sensor, DistanceSensor)
        mount = devices.distance_sensor_mount
        assert mount is not None
        np.testing.assert_allclose(mount, M)
        assert devices.identities()["distance_sensor"]["port"] == twin.port
    finally:
        twin.close()


def test_rotation_order_is_x_then_y_then_z_about_fixed_axes() -> None:
    M = SensorMount(rotation_deg=(90.0, 90.0, 0.0)).matrix()
    # rot_y(90) @ rot_x(90): the sensor's z (beam) first turned by x to -y, then y leaves -y alone
    np.testing.assert_allclose(M[:3, 2], [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(M[:3, 0], [0.0, 0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[distance_sensor]\ndriver = "keyence_il"\nmount = { translation_mm = [1, 2] }', "translation_mm"),
        ('[distance_sensor]\ndriver = "keyence_il"\nmount = { rotation_deg = [0, 0, nan] }', "finite"),
        ('[distance_sensor]\ndriver = "keyence_il"\nmount = { shift = [0, 0, 0] }', "shift"),
    ],
)
def test_a_bad_mount_names_the_field(tmp_path: Path, text: str, message: str) -> None:
    with pytest.raises(ConfigurationError, match=message):
        load_config(write(tmp_path, text))


def test_an_unknown_sensor_driver_is_named(tmp_path: Path) -> None:
    config = load_config(write(tmp_path, '[distance_sensor]\ndriver = "nope"'))
    with pytest.raises(ConfigurationError, match="no distance_sensor named 'nope'; available: keyence_il"):
        open_station(config)


def test_mount_helpers_give_the_measured_point_and_the_focus_reading() -> None:
    beside = SensorMount(translation_mm=(30.0, 0.0, 3.0))
    assert beside.reading_at_plane_mm(68.0) == pytest.approx(65.0)
    np.testing.assert_allclose(beside.point_mm(65.0), [30.0, 0.0, 68.0])
    tilted = SensorMount(translation_mm=(30.0, 0.0, 0.0), rotation_deg=(0.0, -20.0, 0.0))
    z = tilted.reading_at_plane_mm(68.0)
    assert tilted.point_mm(z)[2] == pytest.approx(68.0)
    assert z == pytest.approx(68.0 / np.cos(np.radians(20.0)))
    with pytest.raises(ValueError, match="forward"):
        SensorMount(rotation_deg=(90.0, 0.0, 0.0)).reading_at_plane_mm(68.0)
