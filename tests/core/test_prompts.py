"""The operator-prompt broker: one open prompt, answers by id from any thread, ordered events."""

from __future__ import annotations

import dataclasses
import itertools
import threading
import time
from collections.abc import Callable, Iterator, Mapping

import pytest

from station.prompts import (
    InvalidAnswerError,
    Outcome,
    PromptAnswer,
    PromptBroker,
    PromptBusyError,
    PromptError,
    PromptEvent,
    PromptField,
    PromptHandle,
    PromptWaitTimeoutError,
    UnknownPromptError,
)

FIELDS = (PromptField("x_in", "X micrometer", "in", 0.01), PromptField("y_in", "Y micrometer", "in", 0.0))


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        self.now += 1.0
        return self.now


@pytest.fixture
def broker() -> PromptBroker:
    ids = itertools.count(1)
    return PromptBroker(clock=FakeClock(), new_id=lambda: f"p{next(ids)}")


class Waiter:
    """Waits on a handle in a thread, as the runner's thread would."""

    def __init__(self, handle: PromptHandle, timeout: float | None = None) -> None:
        self.result: PromptAnswer | PromptError | None = None
        self._thread = threading.Thread(target=self._run, args=(handle, timeout), daemon=True)
        self._thread.start()

    def _run(self, handle: PromptHandle, timeout: float | None) -> None:
        try:
            self.result = handle.wait(timeout)
        except PromptError as exc:  # handed to the test thread
            self.result = exc

    def join(self) -> PromptAnswer | PromptError | None:
        self._thread.join(timeout=10)
        assert not self._thread.is_alive(), "the waiting thread never woke up"
        return self.result


@pytest.fixture
def waiters() -> Iterator[Callable[[PromptHandle], Waiter]]:
    made: list[Waiter] = []

    def make(handle: PromptHandle) -> Waiter:
        made.append(Waiter(handle))
        return made[-1]

    yield make
    for w in made:  # no thread outlives its test
        w._thread.join(timeout=10)


def test_ask_opens_one_prompt_with_injected_id_and_time(broker: PromptBroker) -> None:
    handle = broker.ask("set X to 0.0100 in, then confirm", kind="table.move", fields=FIELDS, source="table")
    prompt = broker.current()
    assert prompt is not None
    assert prompt == handle.prompt
    assert (prompt.id, prompt.kind, prompt.source, prompt.created_s) == ("p1", "table.move", "table", 1001.0)
    assert [f.name for f in prompt.fields] == ["x_in", "y_in"]
    assert not handle.done()


def test_confirm_from_another_thread_wakes_the_waiter(broker: PromptBroker, waiters) -> None:
    handle = broker.ask("turn the knob", fields=FIELDS)
    waiter = waiters(handle)
    answer = broker.confirm(handle.id, by="api")
    assert waiter.join() == answer
    assert answer.outcome is Outcome.CONFIRMED
    assert answer.confirmed
    assert answer.by == "api"
    assert dict(answer.readings) == {}
    assert broker.current() is None
    assert handle.done()


def test_confirm_with_readings_returns_them_as_floats(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob", fields=FIELDS)
    broker.confirm(handle.id, {"x_in": 0.0102, "y_in": 0})
    answer = handle.wait()
    assert dict(answer.readings) == {"x_in": 0.0102, "y_in": 0.0}
    assert all(type(v) is float for v in answer.readings.values())


def test_cancel_wakes_the_waiter_with_a_cancelled_answer(broker: PromptBroker, waiters) -> None:
    handle = broker.ask("turn the knob")
    waiter = waiters(handle)
    broker.cancel(handle.id, reason="knob stuck", by="operator")
    result = waiter.join()
    assert isinstance(result, PromptAnswer)
    assert result.outcome is Outcome.CANCELLED
    assert not result.confirmed
    assert (result.reason, result.by) == ("knob stuck", "operator")
    assert broker.current() is None


def test_refuses_a_second_prompt_while_one_is_open(broker: PromptBroker) -> None:
    first = broker.ask("first step")
    with pytest.raises(PromptBusyError, match="already open") as info:
        broker.ask("second step")
    assert info.value.open_prompt == first.prompt
    assert broker.current() == first.prompt  # the open one is untouched
    broker.confirm(first.id)
    second = broker.ask("second step")
    assert broker.current() == second.prompt


def test_an_answer_to_a_stale_prompt_is_refused(broker: PromptBroker) -> None:
    old = broker.ask("first step")
    broker.confirm(old.id)
    new = broker.ask("second step")
    with pytest.raises(UnknownPromptError, match=r"p1 is not open.*p2"):
        broker.confirm(old.id)
    with pytest.raises(UnknownPromptError):
        broker.cancel("nonsense")
    assert broker.current() == new.prompt


def test_answering_with_no_prompt_open_is_refused(broker: PromptBroker) -> None:
    with pytest.raises(UnknownPromptError, match="no prompt is open"):
        broker.confirm("p1")


@pytest.mark.parametrize(
    ("readings", "match"),
    [
        ({"z_in": 0.1}, "unknown reading"),
        ({"x_in": float("nan")}, "finite number"),
        ({"x_in": float("inf")}, "finite number"),
        ({"x_in": "0.01"}, "finite number"),
        ({"x_in": True}, "finite number"),
    ],
)
def test_bad_readings_are_refused_and_the_prompt_stays_open(
    broker: PromptBroker, readings: Mapping[str, float], match: str
) -> None:
    handle = broker.ask("turn the knob", fields=FIELDS)
    with pytest.raises(InvalidAnswerError, match=match):
        broker.confirm(handle.id, readings)
    assert broker.current() == handle.prompt
    assert not handle.done()


def test_the_askers_validator_can_refuse_readings(broker: PromptBroker) -> None:
    def validate(readings: Mapping[str, float]) -> None:
        if readings.get("x_in", 0.0) > 1.0:
            raise ValueError("X beyond its travel of 1.0000 in")

    handle = broker.ask("turn the knob", fields=FIELDS, validate=validate)
    with pytest.raises(InvalidAnswerError, match="beyond its travel"):
        broker.confirm(handle.id, {"x_in": 1.5})
    assert broker.current() == handle.prompt
    assert broker.confirm(handle.id, {"x_in": 0.5}).confirmed


def test_wait_with_timeout_leaves_the_prompt_open(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    with pytest.raises(PromptWaitTimeoutError, match="still open"):
        handle.wait(timeout=0.01)
    assert broker.current() == handle.prompt
    with pytest.raises(TimeoutError):  # it is a TimeoutError too
        handle.wait(timeout=0)
    broker.confirm(handle.id)
    assert handle.wait(timeout=0).confirmed


def test_withdraw_closes_the_prompt_so_a_late_answer_is_refused(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    answer = handle.withdraw(reason="nobody answered")
    assert answer.outcome is Outcome.WITHDRAWN
    assert answer.reason == "nobody answered"
    assert broker.current() is None
    with pytest.raises(UnknownPromptError):
        broker.confirm(handle.id)
    assert handle.wait() == answer


def test_withdraw_after_an_answer_returns_that_answer(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    confirmed = broker.confirm(handle.id)
    assert handle.withdraw() == confirmed


def test_negative_wait_timeout_is_refused(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    with pytest.raises(ValueError, match="timeout"):
        handle.wait(timeout=-1)


@pytest.mark.parametrize(
    ("message", "fields", "match"),
    [
        ("  ", (), "message is empty"),
        ("turn", (PromptField("a", "A"), PromptField("a", "A again")), "distinct names"),
    ],
)
def test_ask_refuses_bad_prompts(
    broker: PromptBroker, message: str, fields: tuple[PromptField, ...], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        broker.ask(message, fields=fields)
    assert broker.current() is None


def test_listeners_see_opened_and_closed_in_order(broker: PromptBroker) -> None:
    events: list[PromptEvent] = []
    unsubscribe = broker.subscribe(events.append)
    handle = broker.ask("first")
    broker.cancel(handle.id)
    second = broker.ask("second")
    broker.confirm(second.id)
    assert [(e.kind, e.prompt.message, e.revision) for e in events] == [
        ("opened", "first", 1),
        ("closed", "first", 2),
        ("opened", "second", 3),
        ("closed", "second", 4),
    ]
    assert events[1].answer is not None
    assert events[1].answer.outcome is Outcome.CANCELLED
    assert broker.revision == 4
    unsubscribe()
    broker.ask("third")
    assert len(events) == 4


def test_a_failing_listener_does_not_break_the_broker(
    broker: PromptBroker, caplog: pytest.LogCaptureFixture
) -> None:
    seen: list[str] = []

    def broken(event: PromptEvent) -> None:
        raise RuntimeError("front end crashed")

    broker.subscribe(broken)
    broker.subscribe(lambda e: seen.append(e.kind))
    handle = broker.ask("turn the knob")
    broker.confirm(handle.id)
    assert seen == ["opened", "closed"]
    assert "front end crashed" in caplog.text


def test_a_listener_may_answer_the_prompt_it_is_told_about(broker: PromptBroker) -> None:
    """A simulated operator answers from inside the 'opened' event; events stay in order."""
    kinds: list[str] = []

    def operator(event: PromptEvent) -> None:
        kinds.append(event.kind)
        if event.kind == "opened":
            broker.confirm(event.prompt.id, {"x_in": 0.0102}, by="sim")

    broker.subscribe(operator)
    handle = broker.ask("turn the knob", fields=FIELDS)
    answer = handle.wait(timeout=0)
    assert answer.by == "sim"
    assert dict(answer.readings) == {"x_in": 0.0102}
    assert kinds == ["opened", "closed"]


def test_wait_for_prompt_blocks_until_one_is_asked(broker: PromptBroker) -> None:
    assert broker.wait_for_prompt(timeout=0) is None
    got: list[object] = []
    thread = threading.Thread(target=lambda: got.append(broker.wait_for_prompt(timeout=10)))
    thread.start()
    handle = broker.ask("turn the knob")
    thread.join(timeout=10)
    assert got == [handle.prompt]


def test_many_threads_racing_to_answer_get_exactly_one_answer(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    results: list[str] = []
    lock = threading.Lock()
    start = threading.Barrier(8)

    def answer(i: int) -> None:
        start.wait()
        try:
            broker.confirm(handle.id, by=f"client{i}") if i % 2 else broker.cancel(handle.id, by=f"client{i}")
            outcome = "answered"
        except UnknownPromptError:
            outcome = "refused"
        with lock:
            results.append(outcome)

    threads = [threading.Thread(target=answer, args=(i,)) for i in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=10)
    assert sorted(results) == ["answered"] + ["refused"] * 7
    assert handle.done()


def test_prompts_and_answers_convert_to_plain_data_for_the_api(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob", fields=FIELDS, details={"x_mm": 0.254})
    answer = broker.confirm(handle.id, {"x_in": 0.0102})
    data = dataclasses.asdict(answer)
    assert data["prompt"]["details"] == {"x_mm": 0.254}
    assert data["prompt"]["fields"][0]["name"] == "x_in"
    assert data["readings"] == {"x_in": 0.0102}
    assert data["outcome"] == "confirmed"


def test_a_poller_sees_a_prompt_only_after_every_listener_has_seen_it_open() -> None:
    """What a listener does on 'opened' (the runner: the session now awaits the operator) is done before
    any front end polling current() or wait_for_prompt() finds the prompt."""
    broker = PromptBroker()
    listener_done = threading.Event()
    seen_early: list[object] = []

    def slow_listener(event: PromptEvent) -> None:
        if event.kind == "opened":
            seen_early.append(broker.current())  # not shown yet, even to a listener
            time.sleep(0.2)
            listener_done.set()

    broker.subscribe(slow_listener)
    found: list[bool] = []

    def poll() -> None:
        prompt = broker.wait_for_prompt(timeout=5.0)
        found.append(prompt is not None and listener_done.is_set())

    poller = threading.Thread(target=poll)
    poller.start()
    handle = broker.ask("turn the micrometers")
    poller.join(timeout=5.0)
    assert found == [True]
    assert seen_early == [None]
    assert broker.current() == handle.prompt
    assert broker.current(pending=True) == handle.prompt


def test_a_context_adds_details_to_the_prompts_asked_inside_it_in_its_thread(broker: PromptBroker) -> None:
    """The runner says which position of how many a table move is for; the table asks."""
    other: list[Mapping[str, str | float]] = []
    with broker.context(position=7, positions=40, move="overshoot"):
        handle = broker.ask("set X", details={"x_mm": 0.254, "move": "own"})
        assert handle.prompt.details == {"position": 7, "positions": 40, "move": "own", "x_mm": 0.254}
        broker.confirm(handle.id)

        def elsewhere() -> None:  # another thread asking meanwhile is not in this context
            h = broker.ask("other")
            other.append(h.prompt.details)
            broker.confirm(h.id)

        t = threading.Thread(target=elsewhere)
        t.start()
        t.join(10)
        with broker.context(position=8):
            inner = broker.ask("set Y")
            assert inner.prompt.details == {"position": 8, "positions": 40, "move": "overshoot"}
            broker.confirm(inner.id)
    assert other == [{}]
    after = broker.ask("after")
    assert after.prompt.details == {}
