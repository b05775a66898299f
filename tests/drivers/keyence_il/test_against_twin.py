"""The Keyence IL driver on its twin over a real pty: what only a serial device does (error replies,
garbled, lost and cut replies, a port that vanishes) and the twin's head model (noise, resolution,
incidence)."""

from __future__ import annotations

import os
from collections.abc import Callable

import numpy as np
import pytest
import serial

from drivers.keyence_il import ErrorReplyError, HeadSettings, KeyenceIL, open_distance_sensor
from sim.distance_sensor import DistanceSensorTwin
from station.config import build
from station.devices import (
    DeviceBusyError,
    DeviceConnectionError,
    DeviceProtocolError,
    DeviceTimeoutError,
    OutOfRangeError,
)
from tests.drivers.keyence_il.conftest import FAST_LINK, Target

Driver = Callable[..., KeyenceIL]


def test_the_wire_is_m0_and_its_reply(twin: DistanceSensorTwin, driver_on: Driver, target: Target) -> None:
    s = driver_on()
    s.connect()
    target.distance_mm = 65.0 + 12.345
    d = s.read_mm()
    assert list(twin.received) == ["M0", "M0"]  # connect() checks that the unit answers
    assert d == pytest.approx(77.345, abs=0.01)


def test_garbled_reply_is_a_protocol_error_and_the_next_read_works(
    twin: DistanceSensorTwin, driver_on: Driver, target: Target
) -> None:
    s = driver_on()
    s.connect()
    twin.inject("garble")
    with pytest.raises(DeviceProtocolError, match="unexpected reply"):
        s.read_mm()
    assert s.read_mm() == pytest.approx(target.distance_mm, abs=0.01)


@pytest.mark.parametrize("kind", ["silent", "cut"])
def test_lost_or_cut_reply_times_out_with_what_to_check(
    twin: DistanceSensorTwin, driver_on: Driver, target: Target, kind: str
) -> None:
    s = driver_on()
    s.connect()
    twin.inject(kind)
    with pytest.raises(DeviceTimeoutError, match="baud"):
        s.read_mm()
    # the late or partial bytes are discarded before the next command: its reply answers it
    assert s.read_mm() == pytest.approx(target.distance_mm, abs=0.01)


def test_error_reply_names_the_error_and_the_action(twin: DistanceSensorTwin, driver_on: Driver) -> None:
    s = driver_on()
    s.connect()
    twin.inject("error", code="29")
    with pytest.raises(ErrorReplyError, match=r"communication error.*baud") as info:
        s.read_mm()
    assert info.value.code == "29"
    assert info.value.reply == "ER,M0,29"
    assert isinstance(info.value, DeviceProtocolError)


def test_an_unknown_command_gets_the_units_invalid_command_reply(twin: DistanceSensorTwin) -> None:
    with serial.Serial(twin.port, timeout=1.0) as port:
        port.write(b"XX\r\n")
        assert port.read_until(b"\r\n") == b"ER,XX,00\r\n"


def test_a_port_that_vanishes_is_a_connection_error(twin: DistanceSensorTwin, driver_on: Driver) -> None:
    s = driver_on()
    s.connect()
    twin.unplug()
    with pytest.raises(DeviceConnectionError, match="connect"):
        s.read_mm()
    with pytest.raises(DeviceConnectionError):
        s.read_mm()


def test_a_missing_port_fails_at_connect(tmp_path: os.PathLike[str]) -> None:
    s = KeyenceIL(os.path.join(tmp_path, "ttyUSB9"), link=FAST_LINK)
    with pytest.raises(DeviceConnectionError, match="cannot open"):
        s.connect()


def test_a_port_held_by_another_program_is_busy(twin: DistanceSensorTwin, driver_on: Driver) -> None:
    driver_on().connect()
    with pytest.raises(DeviceBusyError, match="in use"):
        driver_on().connect()


def test_a_silent_unit_fails_at_connect_and_leaves_the_port_closed(
    twin: DistanceSensorTwin, driver_on: Driver
) -> None:
    twin.inject("silent")
    s = driver_on()
    with pytest.raises(DeviceTimeoutError):
        s.connect()
    assert not s.link.is_open


def test_an_amplifier_index_not_in_the_reply_is_a_configuration_problem(driver_on: Driver) -> None:
    s = driver_on(head=HeadSettings(amplifier_index=3))
    with pytest.raises(DeviceProtocolError, match="amplifier_index 3"):
        s.connect()


def test_direction_toward_inverts_the_reading(driver_on: Driver, target: Target) -> None:
    s = driver_on(head=HeadSettings(increases="toward"))
    s.connect()
    target.distance_mm = 70.0  # the unit prints +05.000; read as toward: 65 - 5
    assert s.read_mm() == pytest.approx(60.0, abs=0.01)


def test_steep_incidence_gives_no_reading(
    make_twin: Callable[..., DistanceSensorTwin], target: Target
) -> None:
    twin = make_twin(max_incidence_deg=20.0)
    s = KeyenceIL(twin.port, link=FAST_LINK)
    try:
        s.connect()
        target.tilt_deg = 15.0
        assert s.read_mm() == pytest.approx(70.0, abs=0.01)
        target.tilt_deg = 25.0
        with pytest.raises(OutOfRangeError, match="no valid measurement"):
            s.read_mm()
    finally:
        s.close()


def test_noise_is_the_heads_repeatability_at_its_display_resolution(
    driver_on: Driver, target: Target
) -> None:
    s = driver_on()
    s.connect()
    target.distance_mm = 70.0004
    reads = np.array([s.read_mm() for _ in range(300)])
    steps = (reads - 65.0) / 0.001
    assert np.allclose(steps, np.round(steps), atol=1e-6)  # multiples of the display's 0.001 mm
    assert reads.mean() == pytest.approx(70.0004, abs=0.0005)
    assert 0.0015 < reads.std(ddof=1) < 0.0026  # 2 µm, 1 sigma


def test_built_by_name_from_configuration_values(twin: DistanceSensorTwin) -> None:
    s = build(
        "distance_sensor",
        "keyence_il",
        port=twin.port,
        head={"model": "IL-065"},
        link={"reply_timeout_s": 0.3},
    )
    try:
        s.connect()
        assert s.identity().model == "Keyence IL-065 via DL-RS1A"
        assert s.identity().port == twin.port
    finally:
        s.close()
    with pytest.raises(ValueError, match="measuring_range_mm"):
        open_distance_sensor(twin.port, head={"measuring_range_mm": (80, 60)})
