"""The manual Vernier X-Y table: moves become operator prompts (``station.prompts``).

``ManualXYTable`` satisfies ``station.devices.XYTable`` (mm); the operator sees micrometer readings in
inches of 0.0002 in divisions. ``TerminalPromptClient`` answers prompts from a terminal.
"""

import functools
from collections.abc import Callable
from typing import ParamSpec

from station.devices import XYTable

from ._manual import PROMPT_KIND, X_FIELD, Y_FIELD, ManualXYTable
from ._vernier import DIVISION_IN, MM_PER_INCH, format_in, in_to_mm, is_on_grid, mm_to_in, snap_in
from .terminal import TerminalPromptClient, parse_readings

P = ParamSpec("P")


def _table_factory(cls: Callable[P, XYTable]) -> Callable[P, XYTable]:
    """A registered factory: builds the table unconnected; mypy checks the class is an ``XYTable``."""

    @functools.wraps(cls)
    def build(*args: P.args, **kwargs: P.kwargs) -> XYTable:
        return cls(*args, **kwargs)

    return build


#: Registered as ``table.manual``: the manual table answering through a prompt broker.
open_manual_table = _table_factory(ManualXYTable)


__all__ = [
    "DIVISION_IN",
    "MM_PER_INCH",
    "PROMPT_KIND",
    "X_FIELD",
    "Y_FIELD",
    "ManualXYTable",
    "TerminalPromptClient",
    "format_in",
    "in_to_mm",
    "is_on_grid",
    "mm_to_in",
    "open_manual_table",
    "parse_readings",
    "snap_in",
]
