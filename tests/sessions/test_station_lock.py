"""Issue 18, the station lock (table row 11): listing never makes a session start fail, and whoever sees
a session's final state can start the next one at once."""

from __future__ import annotations

import threading
from pathlib import Path

from station.kinds import get_plan
from station.plans import parse_params
from station.record import EventRow, Record, SessionLockError, lock_holder
from station.runner import SessionRunner, SessionState
from station.testing import FakeStation
from tests.sessions.conftest import sid_of

LOOPS = 200


def _source(record: Record) -> str:
    """A small validation (three positions) on the in-process fakes, to measure again."""
    plan = get_plan("validation")
    params = parse_params(plan, {"pattern_um": [[0, 0], [254, 0], [0, 254]]})
    runner = SessionRunner(record, plan, params, devices=FakeStation().devices())
    assert runner.run() is SessionState.SUCCEEDED, runner.error
    return sid_of(runner)


def _tiny_session(record: Record, source: str) -> SessionRunner:
    """A re-analysis of ``source``: a real session of a real plan, a tenth of a second long."""
    plan = get_plan("reanalyse")
    return SessionRunner(record, plan, parse_params(plan, {"session": source}), devices=None)


class _Lister(threading.Thread):
    """Asks who holds the station about 2,000 times a second (what ``station sessions`` and the
    service's ``GET /station`` do) until told to stop; the pause lets the session's thread have the
    interpreter (a loop without one would starve it)."""

    def __init__(self, data_dir: Path) -> None:
        super().__init__(name="lister", daemon=True)
        self.data_dir = data_dir
        self.done = threading.Event()
        self.count = 0

    def run(self) -> None:
        while not self.done.wait(0.0005):
            lock_holder(self.data_dir)
            self.count += 1


class _Started:
    """A runner in a thread of its own; ``settled`` is set when it reports ``succeeded`` or its thread
    ends (whichever comes first); ``errors`` holds what ``run()`` raised."""

    def __init__(self, runner: SessionRunner) -> None:
        self.runner = runner
        self.settled = threading.Event()
        self.errors: list[BaseException] = []
        runner.subscribe(self._on_event)
        self.thread = threading.Thread(target=self._run, name="session")
        self.thread.start()

    def _on_event(self, event: EventRow) -> None:
        if event.type == "state" and event.data["state"] == "succeeded":
            self.settled.set()

    def _run(self) -> None:
        try:
            self.runner.run()
        except BaseException as exc:  # noqa: BLE001 - reported by the test
            self.errors.append(exc)
        finally:
            self.settled.set()


def test_whoever_sees_succeeded_starts_the_next_session_at_once_while_others_list(record: Record) -> None:
    """200 times: a session runs in its thread; the moment it reports ``succeeded`` (the state as every
    client sees it), the next session starts, without waiting for the previous thread, and must get
    the station, while another thread lists the station's holder without pause."""
    source = _source(record)
    lister = _Lister(record.data_dir)
    lister.start()
    started: list[_Started] = []
    try:
        for _ in range(LOOPS):
            current = _Started(_tiny_session(record, source))
            started.append(current)
            current.settled.wait(60)  # a hang fails through pytest-timeout
            if current.errors or current.runner.state is not SessionState.SUCCEEDED:
                break
    finally:
        lister.done.set()
        lister.join(30)
        for s in started:
            s.thread.join(60)
    failures = [
        f"start {i}: {s.errors[0] if s.errors else s.runner.state}" for i, s in enumerate(started) if s.errors
    ]
    assert failures == [], failures[:3]
    assert len(started) == LOOPS
    rows = record.list_sessions()
    assert len(rows) == LOOPS + 1
    assert {r.state for r in rows} == {"succeeded"}  # none was taken for a dead one (interrupted)
    assert lister.count > LOOPS  # the listing ran all along


def test_the_next_start_happens_while_the_previous_session_is_still_in_its_thread(record: Record) -> None:
    """The start above is not merely after the old thread ended: here the next session is started from
    inside the ``succeeded`` listener itself (the old runner's thread is still in the station lock's
    block, recording), and gets the station."""
    source = _source(record)
    first = _tiny_session(record, source)
    second = _tiny_session(record, source)
    outcome: list[object] = []

    def start_next(event: object) -> None:
        if getattr(event, "type", None) == "state" and event.data["state"] == "succeeded":  # type: ignore[attr-defined]
            try:
                outcome.append(second.start())
            except SessionLockError as exc:  # pragma: no cover - reported below
                outcome.append(exc)

    first.subscribe(start_next)
    assert first.run() is SessionState.SUCCEEDED
    assert outcome, "the first session never reported succeeded"
    started = outcome[0]
    assert isinstance(started, threading.Thread), started
    started.join(60)
    assert second.state is SessionState.SUCCEEDED, second.error
    assert record.get_session(sid_of(first)).state == "succeeded"
    assert record.get_session(sid_of(second)).state == "succeeded"
