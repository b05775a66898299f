"""The terminal prompt client answers through the broker like any front end (stdin/stdout injected)."""

from __future__ import annotations

import io
import itertools
import threading
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import pytest

from drivers.xy_table import ManualXYTable, TerminalPromptClient, parse_readings
from station.devices import OperatorCancelledError, TablePosition
from station.prompts import Outcome, PromptBroker, PromptField

WAIT_S = 10.0


@pytest.fixture
def broker() -> PromptBroker:
    ids = itertools.count(1)
    return PromptBroker(clock=lambda: 0.0, new_id=lambda: f"p{next(ids)}")


@pytest.fixture
def runner(broker: PromptBroker) -> Iterator[ThreadPoolExecutor]:
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="runner") as pool:
        yield pool
        left_open = broker.current()
        if left_open is not None:
            broker.cancel(left_open.id, reason="test over")


def _move(broker: PromptBroker, runner: ThreadPoolExecutor, x: float, y: float) -> Future[TablePosition]:
    return runner.submit(ManualXYTable(broker, name="table").move_to, x, y)


def _client(broker: PromptBroker, typed: str) -> tuple[TerminalPromptClient, io.StringIO]:
    out = io.StringIO()
    return TerminalPromptClient(broker, stdin=io.StringIO(typed), stdout=out, name="tty"), out


def test_enter_confirms_as_asked(broker: PromptBroker, runner: ThreadPoolExecutor) -> None:
    moving = _move(broker, runner, 0.254, 0.0)
    client, out = _client(broker, "\n")
    answer = client.answer_one(timeout=WAIT_S)
    assert answer is not None
    assert answer.confirmed
    assert answer.by == "tty"
    assert "set X to 0.0100 in, Y to 0.0000 in, then confirm" in out.getvalue()
    assert "c = cancel" in out.getvalue()
    assert moving.result(timeout=WAIT_S).x_mm == pytest.approx(0.254)


@pytest.mark.parametrize(
    "typed", ["0.0104 0.0002\n", "x_in=0.0104, y_in=0.0002\n", "y_in=0.0002 x_in=0.0104\n"]
)
def test_typed_readings_confirm_with_what_was_set(
    broker: PromptBroker, runner: ThreadPoolExecutor, typed: str
) -> None:
    moving = _move(broker, runner, 0.254, 0.0)
    client, _ = _client(broker, typed)
    client.answer_one(timeout=WAIT_S)
    got = moving.result(timeout=WAIT_S)
    assert (got.x_mm, got.y_mm) == (pytest.approx(0.0104 * 25.4), pytest.approx(0.0002 * 25.4))


def test_c_cancels(broker: PromptBroker, runner: ThreadPoolExecutor) -> None:
    moving = _move(broker, runner, 0.254, 0.0)
    client, _ = _client(broker, "c\n")
    answer = client.answer_one(timeout=WAIT_S)
    assert answer is not None
    assert answer.outcome is Outcome.CANCELLED
    with pytest.raises(OperatorCancelledError, match="cancelled at the terminal"):
        moving.result(timeout=WAIT_S)


def test_bad_input_is_explained_and_asked_again(broker: PromptBroker, runner: ThreadPoolExecutor) -> None:
    moving = _move(broker, runner, 0.254, 0.0)
    client, out = _client(broker, "abc\n0.01013\n0.0102\n")
    answer = client.answer_one(timeout=WAIT_S)
    assert answer is not None
    assert dict(answer.readings) == {"x_in": pytest.approx(0.0102)}
    text = out.getvalue()
    assert "Not accepted: x_in: 'abc' is not a number" in text
    assert "did you mean 0.0102 in" in text
    assert moving.result(timeout=WAIT_S).x_mm == pytest.approx(0.0102 * 25.4)


def test_end_of_input_leaves_the_prompt_open_for_others(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")
    client, _ = _client(broker, "")
    with pytest.raises(EOFError):
        client.answer_one(timeout=WAIT_S)
    assert broker.current() == handle.prompt


def test_a_prompt_answered_elsewhere_is_reported_as_gone(broker: PromptBroker) -> None:
    handle = broker.ask("turn the knob")

    class SlowTyper(io.StringIO):
        # The page answers while the operator types. [override]: typeshed's StringIO also inherits
        # _IOBase's bytes readline, and typeshed ignores the same error on its own str readline.
        def readline(self, size: int | None = -1) -> str:  # type: ignore[override]
            broker.confirm(handle.id, by="api")
            return "\n"

    out = io.StringIO()
    client = TerminalPromptClient(broker, stdin=SlowTyper(), stdout=out)
    assert client.answer_one(timeout=WAIT_S) is None
    assert "already answered elsewhere" in out.getvalue()
    assert handle.wait(timeout=0).by == "api"


def test_no_prompt_within_the_timeout_returns_none(broker: PromptBroker) -> None:
    client, out = _client(broker, "\n")
    assert client.answer_one(timeout=0) is None
    assert out.getvalue() == ""


def test_serve_answers_until_the_input_ends(broker: PromptBroker, runner: ThreadPoolExecutor) -> None:
    client, _ = _client(broker, "\nc\n")
    stop = threading.Event()
    serving = threading.Thread(target=client.serve, args=(stop,), kwargs={"poll_s": 0.01})
    serving.start()
    try:
        assert _move(broker, runner, 0.254, 0.0).result(timeout=WAIT_S).x_mm == pytest.approx(0.254)
        with pytest.raises(OperatorCancelledError):
            _move(broker, runner, 0.508, 0.0).result(timeout=WAIT_S)
        broker.ask("one more")  # the input has ended: serve returns and leaves this one open
        serving.join(timeout=WAIT_S)
        assert not serving.is_alive()
        assert broker.current() is not None
    finally:
        stop.set()
        serving.join(timeout=WAIT_S)


def test_serve_stops_when_asked(broker: PromptBroker) -> None:
    # Asked to stop before it starts: it returns without showing or answering the open prompt, though
    # an Enter is waiting on its input.
    handle = broker.ask("left for the page")
    client, out = _client(broker, "\n")
    stop = threading.Event()
    stop.set()
    client.serve(stop, poll_s=0.01)
    assert out.getvalue() == ""
    assert broker.current() == handle.prompt
    broker.cancel(handle.id, reason="test over")
    # Asked to stop while it waits for a prompt: it returns within its poll.
    idle, _ = _client(broker, "\n")
    stop = threading.Event()
    serving = threading.Thread(target=idle.serve, args=(stop,), kwargs={"poll_s": 0.01})
    serving.start()
    stop.set()
    serving.join(timeout=WAIT_S)
    assert not serving.is_alive()


@pytest.mark.parametrize(
    ("typed", "match"),
    [
        ("0.1 0.2 0.3", "too many readings"),
        ("z_in=0.1", "unknown reading 'z_in'"),
        ("x_in=zero", "not a number"),
    ],
)
def test_parse_readings_explains_mistakes(typed: str, match: str) -> None:
    broker = PromptBroker()
    prompt = broker.ask("turn", fields=(PromptField("x_in", "X"), PromptField("y_in", "Y"))).prompt
    with pytest.raises(ValueError, match=match):
        parse_readings(typed, prompt)


def test_parse_readings_refuses_readings_for_a_prompt_without_fields() -> None:
    prompt = PromptBroker().ask("check the lamp").prompt
    with pytest.raises(ValueError, match="takes no readings"):
        parse_readings("0.1", prompt)
