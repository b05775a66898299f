"""The runner with a distance sensor: z read with every capture, recorded with it; a reading the
sensor cannot give leaves the capture without z (and says why); a garbled reply is read again; a lost
link fails the step; the sensor is connected and closed with the other devices."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any

import pytest

from station.devices import DeviceConnectionError, DeviceIdentity, DeviceProtocolError
from station.kinds import get_plan
from station.plans import parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeDistanceSensor, FakeStation
from tests.sessions.conftest import EventLog, results_of, sid_of


def run(record: Record, fake: FakeStation, **params: Any) -> tuple[SessionRunner, EventLog]:
    plan = get_plan("repeatability")
    params = {"cycles": 3, "warmup_cycles": 0, "joints": [2], "settle_s": 0.0, **params}
    r = SessionRunner(record, plan, parse_params(plan, params), devices=fake.devices())
    log = EventLog()
    r.subscribe(log)
    r.run()
    return r, log


def test_z_is_recorded_with_each_capture_and_rp_is_reported_in_3d(tmp_path: Path) -> None:
    z = itertools.count(68.0, 0.001)
    sensor = FakeDistanceSensor(lambda: next(z))
    fake = FakeStation(distance_sensor=sensor)
    with Record(tmp_path) as record:
        r, log = run(record, fake)
        assert r.state is SessionState.SUCCEEDED, r.error
        caps = record.captures(sid_of(r))
        assert [c.z_mm for c in caps] == pytest.approx([68.0, 68.001, 68.002, 68.003])
        assert [c.meta["z_mm"] for c in caps] == [c.z_mm for c in caps]
        assert [e.data["z_mm"] for e in log.of("measurement")] == [c.z_mm for c in caps]
        results = results_of(record, r)
        entry = results["tests"]["J2"]
        assert results["rp3d_mm"] == {"J2": entry["rp3d_mm"]}
        assert entry["rp3d_mm"] > entry["rp_mm"]  # the fake arm is exact: z's 1 um steps dominate
        # connected with the others, identified, closed at the end
        assert sensor.calls_of("connect") == [()]
        assert sensor.calls_of("close") == [()]
        (connected,) = log.of("connected")
        assert connected.data["devices"]["distance_sensor"]["model"] == "fake distance sensor"


class FirmwareOnConnect(FakeDistanceSensor):
    """A sensor that reports its firmware only once connected, as the real heads do."""

    def identity(self) -> DeviceIdentity:
        return DeviceIdentity(
            model=self.MODEL, serial="fake-1", port="in-process", firmware="2.1" if self.connected else None
        )


def test_the_session_row_keeps_the_identities_the_devices_report_once_connected(tmp_path: Path) -> None:
    fake = FakeStation(distance_sensor=FirmwareOnConnect(lambda: 68.0))
    with Record(tmp_path) as record:
        r, log = run(record, fake)
        assert r.state is SessionState.SUCCEEDED, r.error
        (connected,) = log.of("connected")
        assert connected.data["devices"]["distance_sensor"]["firmware"] == "2.1"
        row = record.get_session(sid_of(r))
        assert row.identities == connected.data["devices"]  # not what the devices said before connecting


def test_without_a_sensor_the_results_are_as_before(tmp_path: Path) -> None:
    with Record(tmp_path) as record:
        r, _ = run(record, FakeStation())
        assert r.state is SessionState.SUCCEEDED, r.error
        assert all(c.z_mm is None for c in record.captures(sid_of(r)))
        results = results_of(record, r)
        assert "rp3d_mm" not in results
        assert not any("3d" in k for k in results["tests"]["J2"])


def test_no_valid_distance_leaves_the_capture_without_z_and_says_why(tmp_path: Path) -> None:
    reads = iter([68.0, None, 68.0, 68.0])
    fake = FakeStation(distance_sensor=FakeDistanceSensor(lambda: next(reads)))
    with Record(tmp_path) as record:
        r, log = run(record, fake)
        assert r.state is SessionState.SUCCEEDED, r.error
        caps = record.captures(sid_of(r))
        assert [c.z_mm for c in caps] == [68.0, None, 68.0, 68.0]
        assert "measuring range" in caps[1].meta["z_error"]
        assert any("no z with this capture" in e.data["message"] for e in log.of("warning"))
        entry = results_of(record, r)["tests"]["J2"]
        assert "rp3d_mm" not in entry
        assert "no z on 1 of 3 cycle captures" in entry["rp3d_error"]
        assert "rp_mm" in entry


def test_a_garbled_reply_is_read_again(tmp_path: Path) -> None:
    sensor = FakeDistanceSensor(68.0)
    sensor.fail_on("read_mm", DeviceProtocolError("garbled"), nth=2)
    with Record(tmp_path) as record:
        r, log = run(record, FakeStation(distance_sensor=sensor))
        assert r.state is SessionState.SUCCEEDED, r.error
        assert all(c.z_mm == 68.0 for c in record.captures(sid_of(r)))
        assert len(sensor.calls_of("read_mm")) == 5
        assert any("reading again" in e.data["message"] for e in log.of("warning"))


def test_a_lost_sensor_fails_the_session_and_keeps_what_was_captured(tmp_path: Path) -> None:
    sensor = FakeDistanceSensor(68.0)
    sensor.fail_on("read_mm", DeviceConnectionError("cable pulled: connect() again"), nth=3)
    fake = FakeStation(distance_sensor=sensor)
    with Record(tmp_path) as record:
        r, _ = run(record, fake)
        assert r.state is SessionState.FAILED
        assert r.error is not None
        assert "cable pulled" in r.error
        assert [c.z_mm for c in record.captures(sid_of(r))] == [68.0, 68.0]
        assert sensor.calls_of("close") == [()]
