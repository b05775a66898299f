"""Fixtures for plan and runner tests on the in-process fakes (station.testing)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from station.record import EventRow, Record
from station.runner import SessionRunner
from station.testing import FakeStation


def sid_of(runner: SessionRunner) -> str:
    """The runner's session id (it has one once it ran)."""
    assert runner.session_id is not None, "the runner created no session"
    return runner.session_id


def results_of(record: Record, runner: SessionRunner) -> dict[str, Any]:
    """The recorded results of the runner's session (failing the test if there are none)."""
    results = record.get_session(sid_of(runner)).results
    assert results is not None, f"session {runner.session_id} has no results: {runner.error}"
    return results


@pytest.fixture
def record(tmp_path: Path) -> Iterator[Record]:
    rec = Record(tmp_path / "data")
    yield rec
    rec.close()


@pytest.fixture
def fake() -> FakeStation:
    return FakeStation()


class EventLog:
    """Collects a runner's events (listener) for assertions."""

    def __init__(self) -> None:
        self.events: list[EventRow] = []

    def __call__(self, event: EventRow) -> None:
        self.events.append(event)

    def states(self) -> list[str]:
        return [e.data["state"] for e in self.events if e.type == "state"]

    def of(self, kind: str) -> list[EventRow]:
        return [e for e in self.events if e.type == kind]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """A data directory with one validation session (on the in-process fakes), closed."""
    from station.kinds import get_plan
    from station.plans import parse_params
    from station.runner import SessionRunner, SessionState

    data = tmp_path_factory.mktemp("recorded") / "data"
    with Record(data) as rec:
        plan = get_plan("validation")
        params = parse_params(plan, {"pattern_um": [[0, 0], [254, 0], [0, 254]]})
        runner = SessionRunner(rec, plan, params, devices=FakeStation().devices())
        assert runner.run() is SessionState.SUCCEEDED, runner.error
        assert runner.session_id is not None
        return data, runner.session_id
