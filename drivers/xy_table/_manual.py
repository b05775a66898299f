"""The manual Vernier X-Y table: every move is an operator prompt, answered through station.prompts."""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Mapping

from station.devices import (
    DeviceError,
    DeviceIdentity,
    DeviceTimeoutError,
    MotionRejectedError,
    OperatorCancelledError,
    TablePosition,
)
from station.prompts import Outcome, PromptBroker, PromptBusyError, PromptField, PromptHandle

from ._vernier import DIVISION_IN, format_in, in_to_mm, is_on_grid, mm_to_in, snap_in

log = logging.getLogger(__name__)

PROMPT_KIND = "table.move"
#: Targets farther than this (mm) are outside any micrometer table's travel.
_FAR_MM = 1e6
X_FIELD = "x_in"
Y_FIELD = "y_in"


class ManualXYTable:
    """An X-Y table turned by hand with two micrometers (inches, 0.0002 in per division).

    The interface is in mm; ``move_to`` asks the operator to set both micrometers to the nearest
    whole division ("set X to 0.0100 in, Y to 0.0000 in, then confirm") and blocks the calling thread
    until they confirm, optionally with the readings actually set, or cancel.

    Parameters
    ----------
    broker
        The station's prompt broker; the API, a terminal or a simulated operator answers through it.
    name
        Shown at the start of each prompt.
    x_travel_in, y_travel_in
        Micrometer readings (inches) the table can be set to, inclusive; moves outside are rejected.
    origin_in
        Micrometer readings (X, Y) at table position (0 mm, 0 mm).
    initial
        The position the table is known to be at, if any; otherwise ``position()`` raises until a move
        has been confirmed.
    """

    def __init__(
        self,
        broker: PromptBroker,
        *,
        name: str = "X-Y table",
        x_travel_in: tuple[float, float] = (0.0, 1.0),
        y_travel_in: tuple[float, float] = (0.0, 1.0),
        origin_in: tuple[float, float] = (0.0, 0.0),
        initial: TablePosition | None = None,
    ) -> None:
        for label, (lo, hi) in (("x_travel_in", x_travel_in), ("y_travel_in", y_travel_in)):
            if not lo < hi:
                raise ValueError(f"{label} must be (low, high) with low < high, got {(lo, hi)}")
        self._broker = broker
        self._name = name
        self._travel = {X_FIELD: x_travel_in, Y_FIELD: y_travel_in}
        self._origin_in = origin_in
        self._position = initial
        self._lock = threading.Lock()
        self._connected = False
        self._pending: PromptHandle | None = None

    # ------------------------------------------------------------------ lifecycle

    def connect(self) -> None:
        """Nothing to open: the table is a person with two micrometers; marks the table in use."""
        self._connected = True

    def close(self) -> None:
        """Withdraw this table's open prompt, if any (the operator is told); safe to call twice."""
        self._connected = False
        pending = self._pending
        if pending is not None:
            pending.withdraw(reason=f"{self._name} was closed")

    def identity(self) -> DeviceIdentity:
        """The manual table as configured: its travel in inches and its micrometers' division."""
        (x0, x1), (y0, y1) = self._travel[X_FIELD], self._travel[Y_FIELD]
        return DeviceIdentity(
            model=(
                f"manual Vernier X-Y table, {DIVISION_IN} in divisions, "
                f"X {x0:g}-{x1:g} in, Y {y0:g}-{y1:g} in"
            ),
            serial=self._name,
            port="operator prompts",
            firmware=None,
        )

    def check_target(self, x_mm: float, y_mm: float) -> None:
        """Raise what ``move_to`` would before asking anything: non-finite values, travel. No side effects."""
        for axis, value in (("x_mm", x_mm), ("y_mm", y_mm)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise MotionRejectedError(f"{self._name}: {axis} must be a finite number, got {value!r}")
        if max(abs(x_mm), abs(y_mm)) > _FAR_MM:  # no micrometer reading exists: no rounding either
            raise MotionRejectedError(
                f"{self._name}: target ({x_mm:g}, {y_mm:g}) mm is outside its travel "
                f"{format_in(self._travel[X_FIELD][0])} to {format_in(self._travel[X_FIELD][1])}"
            )
        x_in, y_in = self.readings_for(x_mm, y_mm)
        self._check_travel({X_FIELD: x_in, Y_FIELD: y_in}, what=f"target ({x_mm:g}, {y_mm:g}) mm")

    # ------------------------------------------------------------------ conversions

    def readings_for(self, x_mm: float, y_mm: float) -> tuple[float, float]:
        """The micrometer readings (in, snapped to whole divisions) that put the table at (x, y) mm."""
        return (
            snap_in(self._origin_in[0] + mm_to_in(x_mm)),
            snap_in(self._origin_in[1] + mm_to_in(y_mm)),
        )

    def position_for(self, x_in: float, y_in: float) -> TablePosition:
        """The table position (mm) of micrometer readings (in)."""
        return TablePosition(in_to_mm(x_in - self._origin_in[0]), in_to_mm(y_in - self._origin_in[1]))

    # ------------------------------------------------------------------ XYTable

    def position(self) -> TablePosition:
        """The last confirmed position."""
        if self._position is None:
            raise DeviceError(
                f"{self._name}: position unknown, no move confirmed yet; call move_to so the operator "
                "sets and confirms the micrometers"
            )
        return self._position

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        """Ask the operator to set the table to (x, y) mm; return the position they confirmed.

        Raises MotionRejectedError outside the travel (nothing is asked), OperatorCancelledError if
        the operator cancels, DeviceTimeoutError if nobody answers within ``timeout_s`` (the prompt is
        then withdrawn), DeviceError if another prompt is open.
        """
        if timeout_s is not None and not math.isfinite(timeout_s):
            raise MotionRejectedError(f"{self._name}: timeout_s must be a finite number, got {timeout_s!r}")
        if timeout_s is not None and timeout_s <= 0:
            raise MotionRejectedError(f"{self._name}: timeout_s must be above 0 s, got {timeout_s!r}")
        self.check_target(x_mm, y_mm)
        x_in, y_in = self.readings_for(x_mm, y_mm)
        with self._lock:
            target = self.position_for(x_in, y_in)
            current = self._position
            if current is not None and self.readings_for(current.x_mm, current.y_mm) == (x_in, y_in):
                log.debug("%s already at %s; nothing to ask", self._name, target)
                return current
            message = f"{self._name}: set X to {format_in(x_in)}, Y to {format_in(y_in)}, then confirm"
            try:
                handle = self._broker.ask(
                    message,
                    kind=PROMPT_KIND,
                    fields=(
                        PromptField(X_FIELD, "X micrometer", "in", x_in),
                        PromptField(Y_FIELD, "Y micrometer", "in", y_in),
                    ),
                    source=self._name,
                    details={
                        "x_mm": target.x_mm,
                        "y_mm": target.y_mm,
                        "division_in": DIVISION_IN,
                    },
                    validate=self._validate_readings,
                )
            except PromptBusyError as exc:
                raise DeviceError(f"{self._name}: cannot ask for the move: {exc}") from exc
            self._pending = handle
            try:
                answer = handle.wait(timeout_s)
            except TimeoutError:
                answer = handle.withdraw(reason=f"no answer within {timeout_s} s")
            finally:
                self._pending = None
            if answer.outcome is Outcome.WITHDRAWN:
                raise DeviceTimeoutError(
                    f"{self._name}: nobody confirmed the move to X {format_in(x_in)}, Y {format_in(y_in)} "
                    f"within {timeout_s} s; the prompt was withdrawn and the table is where the operator "
                    "left it: check the micrometers, then move again"
                )
            if answer.outcome is Outcome.CANCELLED:
                raise OperatorCancelledError(
                    f"{self._name}: the operator cancelled the move to X {format_in(x_in)}, "
                    f"Y {format_in(y_in)}{': ' + answer.reason if answer.reason else ''}; "
                    + self._last_confirmed_text()
                )
            set_x = answer.readings.get(X_FIELD, x_in)
            set_y = answer.readings.get(Y_FIELD, y_in)
            self._position = self.position_for(set_x, set_y)
            log.info(
                "%s confirmed at X %s, Y %s = %s",
                self._name,
                format_in(set_x),
                format_in(set_y),
                self._position,
            )
            return self._position

    # ------------------------------------------------------------------ checks

    def _last_confirmed_text(self) -> str:
        if self._position is None:
            return "no position was confirmed before"
        x, y = self._position.x_mm, self._position.y_mm
        x_in, y_in = self.readings_for(x, y)
        # in the micrometers' unit, as the operator reads them; the table position in mm in brackets
        return (
            f"the last confirmed position is X {format_in(x_in)}, Y {format_in(y_in)} "
            f"(X {x:.4f} mm, Y {y:.4f} mm)"
        )

    def _check_travel(self, readings: Mapping[str, float], *, what: str) -> None:
        for name, value in readings.items():
            lo, hi = self._travel[name]
            if not lo - DIVISION_IN / 2 <= value <= hi + DIVISION_IN / 2:
                axis = name[0].upper()
                raise MotionRejectedError(
                    f"{self._name}: {what} needs {axis} at {format_in(value)}, outside its travel "
                    f"{format_in(lo)} to {format_in(hi)}"
                )

    def _validate_readings(self, readings: Mapping[str, float]) -> None:
        for name, value in readings.items():
            if not is_on_grid(value):
                raise ValueError(
                    f"{name} = {value} in is not a whole number of 0.0002 in divisions; "
                    f"did you mean {format_in(snap_in(value))}?"
                )
        try:
            self._check_travel(readings, what="the reading")
        except MotionRejectedError as exc:
            raise ValueError(str(exc)) from exc
