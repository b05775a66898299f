"""Fixtures for plan and runner tests on the in-process fakes (station.testing)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from station.record import EventRow, Record
from station.testing import FakeStation


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
