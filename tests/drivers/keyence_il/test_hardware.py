"""On a real DL-RS1A + IL head (``pytest --hardware``, port in ``$STATION_DISTANCE_SENSOR_PORT``), with a
still, flat target inside the head's range: the checks DIALECT.md asks of a real unit."""

from __future__ import annotations

import os

import numpy as np
import pytest

from drivers.keyence_il import open_distance_sensor

pytestmark = pytest.mark.hardware


@pytest.fixture
def port() -> str:
    port = os.environ.get("STATION_DISTANCE_SENSOR_PORT")
    if not port:
        pytest.skip("set STATION_DISTANCE_SENSOR_PORT to the DL-RS1A's serial port")
    return port


def test_a_still_target_reads_within_range_and_repeats(port: str) -> None:
    sensor = open_distance_sensor(port)
    sensor.connect()
    try:
        reads = np.array([sensor.read_mm() for _ in range(50)])
        near, far = sensor.measuring_range_mm
        assert np.all((reads >= near) & (reads <= far))
        assert reads.std(ddof=1) < 0.01, f"spread {reads.std(ddof=1) * 1000:.1f} um on a still target"
        assert sensor.status().ok
    finally:
        sensor.close()
