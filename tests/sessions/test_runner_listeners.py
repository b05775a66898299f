"""The runner's listeners run outside its locks: a listener that blocks, or that calls back into the runner
from another thread, never stalls the runner's control (``station.runner._journal``)."""

from __future__ import annotations

import threading
from typing import Any

from station.kinds import get_plan
from station.plans import parse_params
from station.record import EventRow, Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeStation
from tests.sessions.conftest import EventLog, sid_of

PROMPTLY_S = 5.0
"""Bound on a control call that must not wait for a listener (generous: the machine is shared)."""


def repeatability(record: Record, fake: FakeStation) -> tuple[SessionRunner, EventLog]:
    plan = get_plan("repeatability")
    params = parse_params(plan, {"cycles": 3, "warmup_cycles": 0, "joints": [1], "settle_s": 0.0})
    r = SessionRunner(record, plan, params, devices=fake.devices())
    log = EventLog()
    r.subscribe(log)
    return r, log


def call_in_thread(call: Any) -> bool:
    """Run ``call()`` in another thread; whether it returned within ``PROMPTLY_S``."""
    returned = threading.Event()

    def target() -> None:
        call()
        returned.set()

    threading.Thread(target=target, daemon=True).start()
    return returned.wait(PROMPTLY_S)


def control(r: SessionRunner) -> None:
    """What a client does meanwhile: read the progress, pause, resume."""
    r.progress()
    r.pause()
    r.resume()


def test_abort_returns_while_a_listener_blocks(record: Record, fake: FakeStation) -> None:
    r, log = repeatability(record, fake)
    blocked, release = threading.Event(), threading.Event()

    def stuck(e: EventRow) -> None:
        if e.type == "step_started" and e.data["index"] == 1:
            blocked.set()
            release.wait(60)

    r.subscribe(stuck)
    thread = r.start()
    assert blocked.wait(30), "the session never reached step 1"
    try:
        assert call_in_thread(r.abort), "abort waited for a listener"
        # abort's effects do not wait for the listener either: the state is written, the arm stopped
        assert r.state is SessionState.ABORTING
        assert record.get_session(sid_of(r)).state == "aborting"
        fake.robot.assert_called("stop")
    finally:
        release.set()
    thread.join(60)
    assert not thread.is_alive()
    assert r.state is SessionState.ABORTED
    assert record.get_session(sid_of(r)).state == "aborted"
    assert log.states()[-2:] == ["aborting", "aborted"]
    # every event was delivered once, in the order it was recorded
    assert [e.id for e in log.events] == [e.id for e in record.events(sid_of(r))]


def test_a_listener_calling_back_from_another_thread_does_not_deadlock(
    record: Record, fake: FakeStation
) -> None:
    r, log = repeatability(record, fake)
    answered: list[bool] = []

    def calls_back(e: EventRow) -> None:
        if e.type == "step_finished" and e.data["index"] == 0:
            # the listener waits for another thread that controls the runner (an API request, say)
            answered.append(call_in_thread(lambda: control(r)))

    r.subscribe(calls_back)
    assert r.run() is SessionState.SUCCEEDED
    assert answered == [True], "a call into the runner waited for the listener that waited for it"
    states = log.states()
    assert states[0] == "running"
    assert states[-1] == "succeeded"
    assert "pausing" in states
    assert [e.id for e in log.events] == [e.id for e in record.events(sid_of(r))]


def test_a_listener_may_control_the_runner_from_its_own_thread(record: Record, fake: FakeStation) -> None:
    r, log = repeatability(record, fake)
    r.subscribe(lambda e: r.stop() if e.type == "step_started" and e.data["index"] == 1 else None)
    assert r.run() is SessionState.STOPPED
    assert [s.state for s in record.steps(sid_of(r))] == ["done", "done"]
    assert log.states()[-2:] == ["stopping", "stopped"]
