"""The DistanceSensor contract, run against every implementation (the Keyence IL driver on its twin over a
real pty, and the in-process fake): what plans and the runner may rely on."""

from __future__ import annotations

import pytest

from station.devices import (
    DeviceConnectionError,
    DeviceIdentity,
    DistanceSensor,
    OutOfRangeError,
    SensorAlarmError,
)
from tests.drivers.keyence_il.conftest import Subject, Target


def test_is_a_distance_sensor(subject: Subject) -> None:
    assert isinstance(subject.sensor, DistanceSensor)
    assert isinstance(subject.sensor.identity(), DeviceIdentity)
    near, far = subject.sensor.measuring_range_mm
    assert 0 < near < far


def test_reads_the_distance_in_mm(subject: Subject, target: Target) -> None:
    s = subject.sensor
    s.connect()
    for d in (56.0, 68.0, 80.25, 104.0):
        target.distance_mm = d
        assert s.read_mm() == pytest.approx(d, abs=subject.noise_mm)
    assert s.status().ok


def test_no_target_raises_out_of_range_never_a_number(subject: Subject, target: Target) -> None:
    s = subject.sensor
    s.connect()
    target.present = False
    with pytest.raises(OutOfRangeError, match="range"):
        s.read_mm()
    status = s.status()
    assert (status.state, status.ok) == ("out_of_range", False)
    target.present = True
    assert s.read_mm() == pytest.approx(target.distance_mm, abs=subject.noise_mm)


@pytest.mark.parametrize("distance", [40.0, 54.9, 105.1, 150.0])
def test_beyond_the_measuring_range_raises_out_of_range(
    subject: Subject, target: Target, distance: float
) -> None:
    subject.sensor.connect()
    target.distance_mm = distance
    with pytest.raises(OutOfRangeError):
        subject.sensor.read_mm()


def test_alarm_raises_sensor_alarm(subject: Subject) -> None:
    s = subject.sensor
    s.connect()
    subject.set_alarm(True)
    with pytest.raises(SensorAlarmError):
        s.read_mm()
    assert s.status().state == "alarm"
    subject.set_alarm(False)
    assert s.status().ok


def test_lifecycle_connect_twice_close_twice_read_after_close(subject: Subject) -> None:
    s = subject.sensor
    s.connect()
    s.connect()
    s.read_mm()
    s.close()
    s.close()
    with pytest.raises(DeviceConnectionError, match="connect"):
        s.read_mm()
    s.connect()
    s.read_mm()
