"""The core's sub-commands, one module each; ``CORE_COMMANDS`` lists their ``register`` functions."""

from __future__ import annotations

import argparse
from collections.abc import Callable

SubParsers = argparse._SubParsersAction  # type: ignore[type-arg]
Register = Callable[[SubParsers], None]

CORE_COMMANDS: list[Register] = []
