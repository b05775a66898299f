"""``station sim ...``: the simulated station's sub-commands (registered through an entry point)."""

from __future__ import annotations

import importlib
import logging

from station.commands import SubParsers

log = logging.getLogger(__name__)

# Each module defines ``register(subparsers)`` for its ``station sim`` sub-commands.
SIM_COMMAND_MODULES = ("sim.imageset_cli", "sim.controller_cli", "sim.target_cli")


def register(sub: SubParsers) -> None:
    parser = sub.add_parser("sim", help="simulated station: render artifact images and sets, run twins")
    sim_sub = parser.add_subparsers(dest="sim_command", required=True, metavar="SIM_COMMAND")
    for name in SIM_COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name != name:
                raise
            log.debug("%s not present", name)
            continue
        module.register(sim_sub)
