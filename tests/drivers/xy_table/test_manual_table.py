"""The manual table asks the operator through the prompt broker: prompt text, confirm, cancel, timeout.

The table's caller (the runner) waits in a worker thread; the test thread plays the API answering.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from concurrent.futures import Future, ThreadPoolExecutor

import pytest

from drivers.xy_table import PROMPT_KIND, ManualXYTable
from station.devices import (
    DeviceError,
    DeviceTimeoutError,
    OperatorCancelledError,
    TablePosition,
)
from station.prompts import InvalidAnswerError, Prompt, PromptBroker

ANSWER_WAIT_S = 10.0  # generous bound on thread hand-offs; never reached when things work


@pytest.fixture
def broker() -> PromptBroker:
    ids = itertools.count(1)
    return PromptBroker(clock=lambda: 0.0, new_id=lambda: f"p{next(ids)}")


@pytest.fixture
def table(broker: PromptBroker) -> ManualXYTable:
    return ManualXYTable(broker, name="Vernier table", x_travel_in=(0.0, 1.0), y_travel_in=(0.0, 1.0))


@pytest.fixture
def runner(broker: PromptBroker) -> Iterator[ThreadPoolExecutor]:
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="runner") as pool:
        yield pool
        left_open = broker.current()
        if left_open is not None:  # a failed test must not leave the runner thread waiting forever
            broker.cancel(left_open.id, reason="test over")


def _asked(broker: PromptBroker) -> Prompt:
    prompt = broker.wait_for_prompt(timeout=ANSWER_WAIT_S)
    assert prompt is not None, "the table never asked the operator"
    return prompt


def _move(
    runner: ThreadPoolExecutor, table: ManualXYTable, x_mm: float, y_mm: float
) -> Future[TablePosition]:
    return runner.submit(table.move_to, x_mm, y_mm)


def test_move_asks_to_set_the_micrometers_in_inches(
    broker: PromptBroker, table: ManualXYTable, runner: ThreadPoolExecutor
) -> None:
    moving = _move(runner, table, 0.254, 0.0)
    prompt = _asked(broker)
    assert prompt.message == "Vernier table: set X to 0.0100 in, Y to 0.0000 in, then confirm"
    assert prompt.kind == PROMPT_KIND
    assert [(f.name, f.unit, f.requested) for f in prompt.fields] == [
        ("x_in", "in", pytest.approx(0.01)),
        ("y_in", "in", pytest.approx(0.0)),
    ]
    assert prompt.details["x_mm"] == pytest.approx(0.254)
    assert not moving.done()  # the runner waits for the operator
    broker.confirm(prompt.id)
    assert moving.result(timeout=ANSWER_WAIT_S) == TablePosition(pytest.approx(0.254), pytest.approx(0.0))  # type: ignore[arg-type]


def test_target_is_rounded_to_a_whole_division(
    broker: PromptBroker, table: ManualXYTable, runner: ThreadPoolExecutor
) -> None:
    moving = _move(runner, table, 0.2567, 0.0)  # 0.010106 in = 50.53 divisions -> 0.0102 in
    prompt = _asked(broker)
    assert "set X to 0.0102 in" in prompt.message
    broker.confirm(prompt.id)
    assert moving.result(timeout=ANSWER_WAIT_S).x_mm == pytest.approx(0.0102 * 25.4)


def test_confirmed_readings_become_the_position(
    broker: PromptBroker, table: ManualXYTable, runner: ThreadPoolExecutor
) -> None:
    moving = _move(runner, table, 0.254, 0.0)
    broker.confirm(_asked(broker).id, {"x_in": 0.0104, "y_in": 0.0002}, by="operator")
    got = moving.result(timeout=ANSWER_WAIT_S)
    assert got.x_mm == pytest.approx(0.0104 * 25.4)
    assert got.y_mm == pytest.approx(0.0002 * 25.4)
    assert table.position() == got


@pytest.mark.parametrize(
    ("readings", "match"),
    [
        ({"x_in": 0.01013}, "not a whole number of 0.0002 in divisions; did you mean 0.0102 in"),
        ({"y_in": 1.2}, "travel"),
    ],
)
def test_readings_off_the_dial_are_refused_and_the_prompt_stays_open(
    broker: PromptBroker,
    table: ManualXYTable,
    runner: ThreadPoolExecutor,
    readings: dict[str, float],
    match: str,
) -> None:
    moving = _move(runner, table, 0.254, 0.0)
    prompt = _asked(broker)
    with pytest.raises(InvalidAnswerError, match=match):
        broker.confirm(prompt.id, readings)
    assert broker.current() == prompt
    broker.confirm(prompt.id, {"x_in": 0.0102})
    assert moving.result(timeout=ANSWER_WAIT_S).x_mm == pytest.approx(0.0102 * 25.4)


def test_cancel_raises_and_keeps_the_last_confirmed_position(
    broker: PromptBroker, table: ManualXYTable, runner: ThreadPoolExecutor
) -> None:
    first = _move(runner, table, 1.0, 1.0)
    broker.confirm(_asked(broker).id)
    start = first.result(timeout=ANSWER_WAIT_S)
    moving = _move(runner, table, 2.0, 2.0)
    broker.cancel(_asked(broker).id, reason="micrometer jammed")
    # every length in the table's unit (the micrometers' inches), the table position in mm in brackets
    expected = (
        r"move to X 0\.0788 in.*jammed.*last confirmed position is X 0\.0394 in, Y 0\.0394 in \(X 1\.0008 mm"
    )
    with pytest.raises(OperatorCancelledError, match=expected):
        moving.result(timeout=ANSWER_WAIT_S)
    assert table.position() == start
    assert broker.current() is None


def test_no_answer_within_the_timeout_withdraws_the_prompt(
    broker: PromptBroker, table: ManualXYTable
) -> None:
    with pytest.raises(DeviceTimeoutError, match=r"nobody confirmed .* within 0.01 s"):
        table.move_to(0.254, 0.0, timeout_s=0.01)
    assert broker.current() is None  # a late answer can no longer land


def test_refuses_to_ask_while_another_prompt_is_open(broker: PromptBroker, table: ManualXYTable) -> None:
    other = broker.ask("check the lamp")
    with pytest.raises(DeviceError, match="already open"):
        table.move_to(0.254, 0.0)
    assert broker.current() == other.prompt


def test_position_is_unknown_until_a_move_is_confirmed(broker: PromptBroker) -> None:
    table = ManualXYTable(broker)
    with pytest.raises(DeviceError, match="position unknown"):
        table.position()
    known = ManualXYTable(broker, initial=TablePosition(1.0, 2.0))
    assert known.position() == TablePosition(1.0, 2.0)


def test_moving_to_where_it_is_asks_nothing(broker: PromptBroker) -> None:
    table = ManualXYTable(broker, initial=TablePosition(0.254, 0.0))
    assert table.move_to(0.2541, 0.0) == TablePosition(0.254, 0.0)
    assert broker.revision == 0


def test_origin_offsets_the_readings(broker: PromptBroker, runner: ThreadPoolExecutor) -> None:
    table = ManualXYTable(broker, origin_in=(0.5, 0.25))
    assert table.readings_for(0.0, 0.0) == (pytest.approx(0.5), pytest.approx(0.25))
    moving = _move(runner, table, -2.54, 0.0)
    prompt = _asked(broker)
    assert "set X to 0.4000 in, Y to 0.2500 in" in prompt.message
    broker.confirm(prompt.id)
    assert moving.result(timeout=ANSWER_WAIT_S).x_mm == pytest.approx(-2.54)


def test_rejects_a_travel_that_is_not_low_to_high(broker: PromptBroker) -> None:
    with pytest.raises(ValueError, match="x_travel_in"):
        ManualXYTable(broker, x_travel_in=(1.0, 0.0))


def test_the_station_builds_it_by_name(broker: PromptBroker) -> None:
    from station.config import build

    table = build("table", "manual", broker=broker, initial=TablePosition(0.0, 0.0))
    assert isinstance(table, ManualXYTable)
    assert table.position() == TablePosition(0.0, 0.0)
