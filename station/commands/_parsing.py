"""The argparse plumbing every command module shares: the sub-parsers' type, a ``register`` function's
type and the record's options (``--data``, ``--database``).

It sits below the command modules and the package's face (``station/commands/__init__.py``, which imports
the command modules by name), so that no command module imports the face or another command module for
these.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    SubParsers = argparse._SubParsersAction[argparse.ArgumentParser]
else:
    SubParsers = argparse._SubParsersAction
Register = Callable[[SubParsers], None]


def add_record_options(p: argparse.ArgumentParser) -> None:
    """``--data DIR`` and ``--database URL``: where the session record lives."""
    p.add_argument(
        "--data", metavar="DIR", help="data directory (default: $STATION_DATA, else ./station-data)"
    )
    p.add_argument("--database", metavar="URL", help="SQLAlchemy URL of the record (default: SQLite in DIR)")


__all__ = ["Register", "SubParsers", "add_record_options"]
