"""The X-Y table's interface: ``XYTable`` and its position (mm; its operator prompt shows inches)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from station.devices._errors import (
    DeviceError,
)
from station.devices._lifecycle import DeviceIdentity


class OperatorCancelledError(DeviceError):
    """The operator cancelled a manual step; nothing was confirmed. Check the device before going on."""


@dataclass(frozen=True)
class TablePosition:
    """A table position in mm, table axes."""

    x_mm: float
    y_mm: float


@runtime_checkable
class XYTable(Protocol):
    """An X-Y positioning table in mm (the manual Vernier table asks an operator to turn it).

    ``move_to`` blocks only the calling thread until the move is done (for the manual table: until the
    operator confirms through ``station.prompts``). A target outside the travel raises
    ``MotionRejectedError`` before anything happens; a cancelled move ``OperatorCancelledError``; no
    answer within ``timeout_s`` ``DeviceTimeoutError``.
    """

    def connect(self) -> None:
        """Make the table ready (for the manual table: nothing to open; it checks its prompt channel)."""

    def close(self) -> None:
        """Release the table (withdraw any open prompt of its own); safe to call twice."""

    def identity(self) -> DeviceIdentity:
        """What the table is (model, travel), as configured."""

    def check_target(self, x_mm: float, y_mm: float) -> None:
        """Raise what ``move_to(x_mm, y_mm)`` would raise before acting (travel, non-finite values).

        No side effects: nothing is asked, nothing moves. Pre-flight checks a whole pattern with it.
        """

    def position(self) -> TablePosition:
        """The last confirmed position (DeviceError if none was confirmed yet)."""

    def move_to(self, x_mm: float, y_mm: float, *, timeout_s: float | None = None) -> TablePosition:
        """Move to an absolute position and return the position actually set (as confirmed)."""


__all__ = [
    "OperatorCancelledError",
    "TablePosition",
    "XYTable",
]
