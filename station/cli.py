"""The ``station`` command line.

Core sub-commands are defined here; packages that the core may not import (``sim``, ``drivers``)
add theirs through the entry-point group ``station.cli``: each entry point is a function
``register(subparsers)`` that adds its sub-parser and sets ``func`` (``args -> exit code``).

Exit codes: 0 success, 1 a measurement or device failed, 2 usage error (argparse's own).
Results go to stdout; progress and logs to stderr only.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Callable, Sequence
from importlib.metadata import entry_points

from station import __version__
from station.commands import CORE_COMMANDS, registers
from station.runtime import tune_allocator

log = logging.getLogger(__name__)

CLI_GROUP = "station.cli"
Handler = Callable[[argparse.Namespace], int]


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The whole command line; with ``command`` (a core sub-command), only that sub-command's parser:
    ``station measure`` then imports what measuring needs, not every sub-command and plug-in."""
    parser = argparse.ArgumentParser(
        prog="station",
        description="Robot calibration station: measure crossed-groove artifact images, run sessions.",
    )
    parser.add_argument("--version", action="version", version=f"station {__version__}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output on stderr")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    core = command if command in CORE_COMMANDS else None
    for register_core in registers([core] if core else None):
        register_core(sub)
    if core:
        return parser
    for ep in sorted(entry_points(group=CLI_GROUP), key=lambda e: e.name):
        try:
            register = ep.load()
        except ImportError as exc:  # a plugin whose dependencies are absent must not break the CLI
            log.warning("station: sub-commands of %s unavailable: %s", ep.name, exc)
            continue
        register(sub)
    return parser


def _command(argv: Sequence[str]) -> str | None:
    """The sub-command named by ``argv`` (its first word that is not an option), if any."""
    return next((a for a in argv if not a.startswith("-")), None)


def _configure_logging(verbosity: int) -> None:
    level = logging.WARNING - 10 * min(verbosity, 2)
    logging.basicConfig(level=level, stream=sys.stderr, format="%(levelname)s %(name)s: %(message)s")


def main(argv: Sequence[str] | None = None) -> int:
    tune_allocator()
    words = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command(words))
    args = parser.parse_args(words)
    _configure_logging(args.verbose)
    handler: Handler = args.func
    try:
        code = handler(args)
        sys.stdout.flush()  # a reader that has gone shows here, not in the interpreter's exit
        return code
    except KeyboardInterrupt:
        print("station: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # whoever read the output has gone (``station sessions | head``): not an error of the station.
        # Later writes (the interpreter's final flush) go nowhere instead of failing again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
        return 141  # 128 + SIGPIPE, as a shell reports a writer its reader left


if __name__ == "__main__":
    sys.exit(main())
