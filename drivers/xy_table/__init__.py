"""The manual Vernier X-Y table: moves become operator prompts (``station.prompts``).

``ManualXYTable`` satisfies ``station.devices.XYTable`` (mm); the operator sees micrometer readings in
inches of 0.0002 in divisions. ``TerminalPromptClient`` answers prompts from a terminal.
"""

from ._manual import PROMPT_KIND, X_FIELD, Y_FIELD, ManualXYTable
from ._vernier import DIVISION_IN, MM_PER_INCH, format_in, in_to_mm, is_on_grid, mm_to_in, snap_in
from .terminal import TerminalPromptClient, parse_readings

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
    "parse_readings",
    "snap_in",
]
