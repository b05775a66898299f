"""The core's sub-commands, one module each; ``CORE_COMMANDS`` names them (sub-command -> module), and
``registers`` imports the modules asked for, so that ``station measure`` loads what measuring needs and
not the record, the reports or the service (about 1 s of start-up per run)."""

from __future__ import annotations

import importlib
from collections.abc import Iterable

from station.commands._parsing import Register, SubParsers

#: Sub-command -> the module that defines it, in the order ``station --help`` lists them.
CORE_COMMANDS: dict[str, str] = {
    "measure": "measure",
    "validate": "validate",
    "sweep": "sweep",
    "camera": "camera",
    "table": "table",
    "run": "run",
    "sessions": "sessions",
    "report": "sessions",
    "export": "sessions",
    "import": "sessions",
    "calibrate": "calibrate",
    "scale-calibration": "scale_calibration",
    "teach": "teach",
}


def registers(commands: Iterable[str] | None = None) -> list[Register]:
    """The ``register`` functions of the modules defining ``commands`` (all of them by default)."""
    wanted = CORE_COMMANDS if commands is None else [c for c in commands if c in CORE_COMMANDS]
    modules = dict.fromkeys(CORE_COMMANDS[c] for c in wanted)
    loaded = [importlib.import_module(f"station.commands.{m}") for m in modules]
    return [module.register for module in loaded]


__all__ = ["CORE_COMMANDS", "Register", "SubParsers", "registers"]
