"""The ``selftest`` session kind (issue 23, item 3) on the simulated station, and its result attached to
every later session of the same controller (``station.selftest_status``)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest

from sim.station import build_sim_station
from station.kinds import KINDS, get_plan
from station.plans import parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.selftest_status import latest_selftest, selftest_check
from tests.sessions.conftest import results_of, sid_of

pytestmark = pytest.mark.timeout(300)


@pytest.fixture
def record(tmp_path: Path) -> Iterator[Record]:
    rec = Record(tmp_path / "data")
    yield rec
    rec.close()


def run(record: Record, kind: str, time_scale: float = 100.0, **params: Any) -> SessionRunner:
    devices = build_sim_station(seed=5, time_scale=time_scale)
    plan = get_plan(kind)
    runner = SessionRunner(record, plan, parse_params(plan, params), devices=devices)
    try:
        runner.run()
    finally:
        devices.close_owned()
    return runner


def check_named(results: dict[str, Any], name: str) -> dict[str, Any]:
    (check,) = [c for c in results["checks"] if c["name"] == name]
    return check


def test_a_self_test_session_is_recorded_and_attached_to_later_sessions(record: Record) -> None:
    before = run(record, "repeatability", cycles=2, warmup_cycles=0, joints=[1])
    assert before.state is SessionState.SUCCEEDED, before.error
    res = results_of(record, before)
    assert res["selftest"] is None
    missing = check_named(res, "selftest")
    assert missing["passed"] is False
    assert missing["severity"] == "warn"  # a warning: the session still succeeded
    assert "station run selftest" in missing["message"]

    # the halt check is left out here: it latches the stop, which only a person at the station clears
    test = run(record, "selftest", checks=["directions", "world", "ready"])
    assert test.state is SessionState.SUCCEEDED, test.error
    res = results_of(record, test)
    assert res["passed"] is True
    assert [c["name"] for c in res["controller_checks"]] == ["directions", "world", "ready"]
    assert all(c["state"] == "passed" for c in res["controller_checks"])
    robot = res["identity"]  # as the controller reports it once connected (armstat's arm type)
    assert robot["model"] == "A465"
    assert "selftest" not in res  # a self-test does not carry one
    KINDS["selftest"].results.model_validate(res)

    after = run(record, "repeatability", cycles=2, warmup_cycles=0, joints=[1])
    assert after.state is SessionState.SUCCEEDED, after.error
    res = results_of(record, after)
    assert res["selftest"]["session_id"] == sid_of(test)
    assert res["selftest"]["passed"] is True
    datetime.fromisoformat(res["selftest"]["when"])
    assert check_named(res, "selftest")["passed"] is True

    # another controller (another serial): the self-test does not hold for it
    other = {**robot, "serial": "another-controller"}
    assert latest_selftest(record, other) is None
    assert latest_selftest(record, {**robot, "port": "/dev/elsewhere"}) is not None  # the port is not it


def test_the_halt_check_latches_the_stop_and_says_so(record: Record) -> None:
    test = run(record, "selftest", time_scale=1.0, checks=["halt"])  # real time: the halt is timed
    assert test.state is SessionState.SUCCEEDED, test.error
    res = results_of(record, test)
    assert res["controller_checks"][0]["state"] == "passed"
    assert res["latched"] is True
    latched = check_named(res, "stop_latched")
    assert latched["passed"] is False
    assert "acknowledge" in latched["message"]


def test_a_failed_self_test_warns_with_what_to_do() -> None:
    when = datetime(2026, 12, 2, tzinfo=UTC).isoformat()
    check = selftest_check({"session_id": "abc", "passed": False, "when": when})
    assert check.passed is False
    assert check.severity == "warn"
    assert "session abc" in check.message
    assert "station run selftest" in check.message
