"""The XYTable contract, run against every implementation.

Each case builds a table whose moves get answered (for the manual table: a simulated operator that
confirms every prompt through the broker, or the simulated station's operator who turns the
simulated world's micrometers).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import pytest

from drivers.xy_table import ManualXYTable
from sim.operator import SimOperator
from sim.world import World
from station.devices import DeviceError, MotionRejectedError, TablePosition, XYTable
from station.prompts import PromptBroker, PromptEvent

HALF_DIVISION_MM = 0.0001 * 25.4


@dataclass(frozen=True)
class TableCase:
    """How to build one implementation, with its usable travel in mm (x_max, y_max)."""

    make: Callable[[], XYTable]
    travel_mm: tuple[float, float]


def _manual_with_operator() -> XYTable:
    broker = PromptBroker()

    def operator(event: PromptEvent) -> None:  # confirms as asked, like a careful person
        if event.kind == "opened":
            broker.confirm(event.prompt.id, by="simulated operator")

    broker.subscribe(operator)
    return ManualXYTable(broker, x_travel_in=(0.0, 1.0), y_travel_in=(0.0, 0.5))


def _manual_in_sim_world() -> XYTable:
    """The manual table in the simulated station: the sim operator turns the world's micrometers."""
    broker = PromptBroker()
    world = World()
    _operators.append(SimOperator(broker, world).start())
    return ManualXYTable(broker, x_travel_in=(0.0, 1.0), y_travel_in=(0.0, 0.5))


_operators: list[SimOperator] = []

CASES = {
    "manual-table": TableCase(_manual_with_operator, travel_mm=(25.4, 12.7)),
    "manual-table-sim-world": TableCase(_manual_in_sim_world, travel_mm=(25.4, 12.7)),
}


@pytest.fixture(params=sorted(CASES))
def case(request: pytest.FixtureRequest) -> TableCase:
    return CASES[request.param]


@pytest.fixture
def table(case: TableCase) -> Iterator[XYTable]:
    yield case.make()
    while _operators:
        _operators.pop().close()


def test_connects_says_what_it_is_and_knows_no_position_before_a_move(
    table: XYTable, case: TableCase
) -> None:
    table.connect()
    table.connect()  # a second connect does nothing
    assert table.identity().model
    with pytest.raises(DeviceError, match="move_to"):
        table.position()  # unknown, not a guess: the error says how to get one
    x_max, y_max = case.travel_mm
    table.check_target(x_max, y_max)  # inside the travel: nothing raised, nothing asked
    with pytest.raises(MotionRejectedError, match="outside its travel"):
        table.check_target(x_max + 0.1, 0.0)
    with pytest.raises(MotionRejectedError):
        table.check_target(float("nan"), 0.0)
    with pytest.raises(DeviceError, match="move_to"):
        table.position()  # checking a target moved nothing
    table.close()
    table.close()


@pytest.mark.parametrize(("x_mm", "y_mm"), [(0.0, 0.0), (0.254, 0.0), (1.0, 2.5), (12.3456, 7.891)])
def test_move_returns_the_position_set_within_half_a_division(
    table: XYTable, x_mm: float, y_mm: float
) -> None:
    got = table.move_to(x_mm, y_mm)
    assert got.x_mm == pytest.approx(x_mm, abs=HALF_DIVISION_MM)
    assert got.y_mm == pytest.approx(y_mm, abs=HALF_DIVISION_MM)
    assert table.position() == got


def test_successive_moves_track_the_last_one(table: XYTable) -> None:
    table.move_to(5.0, 5.0)
    table.move_to(0.5, 1.0)
    assert table.position() == table.move_to(0.5, 1.0)
    assert table.position().x_mm == pytest.approx(0.5, abs=HALF_DIVISION_MM)


@pytest.mark.parametrize("where", ["x_low", "x_high", "y_high"])
def test_rejects_a_target_outside_the_travel_and_stays_put(
    table: XYTable, case: TableCase, where: str
) -> None:
    start = table.move_to(1.0, 1.0)
    x_max, y_max = case.travel_mm
    target = {"x_low": (-0.1, 1.0), "x_high": (x_max + 0.1, 1.0), "y_high": (1.0, y_max + 0.1)}[where]
    with pytest.raises(MotionRejectedError, match="outside its travel"):
        table.move_to(*target)
    assert table.position() == start


def test_accepts_the_ends_of_the_travel(table: XYTable, case: TableCase) -> None:
    x_max, y_max = case.travel_mm
    got = table.move_to(x_max, y_max)
    assert got == TablePosition(pytest.approx(x_max), pytest.approx(y_max))  # type: ignore[arg-type]
