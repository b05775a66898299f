"""What lies on the X-Y table (``station.table_content``): a session asks for what its plan needs before
pre-flight, the station remembers what was confirmed for as long as its devices stay open (in the
record), and a declined prompt ends the session before anything moves, saying what to do (issue 23)."""

from __future__ import annotations

from typing import Any

from station.kinds import get_plan
from station.plans import parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.table_content import needed_content, prompt_message, remembered
from station.testing import FakeStation
from tests.sessions.conftest import EventLog

REPEAT = {"cycles": 2, "warmup_cycles": 0, "joints": [1], "settle_s": 0.0}


def run(record: Record, devices: Any, kind: str, params: dict[str, Any]) -> tuple[SessionRunner, EventLog]:
    plan = get_plan(kind)
    r = SessionRunner(record, plan, parse_params(plan, params), devices=devices)
    log = EventLog()
    r.subscribe(log)
    r.run()
    return r, log


def test_each_plan_declares_what_must_lie_on_the_table() -> None:
    def needs(kind: str, **params: Any) -> str | None:
        plan = get_plan(kind)
        return needed_content(plan, parse_params(plan, params))

    assert needs("validation") == "cross"
    assert needs("validation", artifact="ruler") == "ruler"
    assert needs("camera-calibration") == "target"
    assert needs("repeatability") == needs("selftest") == needs("calibration") == "cross"
    assert needs("calibration", placements=[1, 2]) is None  # the bench's artifacts only
    assert prompt_message("target").startswith("Put the ChArUco calibration target on the X-Y table")
    assert prompt_message("ruler").startswith("Put the ruler on the X-Y table")
    assert "then confirm" in prompt_message("cross")


def test_the_station_asks_once_per_opening_of_its_devices(record: Record, fake: FakeStation) -> None:
    devices = fake.devices()
    first, log1 = run(record, devices, "repeatability", REPEAT)
    assert first.state is SessionState.SUCCEEDED, first.error
    raised = log1.of("prompt_raised")
    assert [e.data["kind"] for e in raised] == ["table_content"]
    assert raised[0].data["message"].startswith("Put the artifact's cross on the X-Y table")
    # asked before the pre-flight, whose scale check grabs a frame
    types = [e.type for e in log1.events]
    assert types.index("table_content") < types.index("preflight")
    assert log1.of("table_content")[0].data | {"opened": ""} == {
        "content": "cross",
        "asked": True,
        "by": "fake-station",
        "confirmed_in": None,
        "opened": "",
    }
    assert remembered(record, devices.opened_id) == ("cross", first.session_id)

    second, log2 = run(record, devices, "repeatability", REPEAT)
    assert second.state is SessionState.SUCCEEDED, second.error
    assert log2.of("prompt_raised") == []  # the same devices: the cross is known to be there
    assert log2.of("table_content")[0].data["asked"] is False
    assert log2.of("table_content")[0].data["confirmed_in"] == first.session_id

    restarted = fake.devices()  # the station opened anew: the table may have changed meanwhile
    assert remembered(record, restarted.opened_id) == (None, None)
    third, log3 = run(record, restarted, "repeatability", REPEAT)
    assert third.state is SessionState.SUCCEEDED, third.error
    assert [e.data["kind"] for e in log3.of("prompt_raised")] == ["table_content"]


def test_a_declined_prompt_ends_the_session_before_anything_moves(record: Record, fake: FakeStation) -> None:
    ruler = {"artifact": "ruler", "pattern_um": [[0, 0], [254, 0], [0, 254]]}
    r, log = run(record, fake.devices(), "validation", ruler)  # the fake's operator has no ruler
    assert r.state is SessionState.FAILED
    assert r.error is not None
    assert "the operator declined to put the ruler on the X-Y table" in r.error
    assert "put the ruler on the X-Y table, then start the session again" in r.error
    assert log.of("preflight") == []
    assert log.of("table_content") == []
    assert fake.table.calls_of("move_to") == []
    assert record.captures(r.session_id or "") == []


def test_nothing_is_remembered_from_a_record_without_it(record: Record) -> None:
    assert remembered(record, "x" * 32) == (None, None)
