"""The core's sub-commands, one module each; ``CORE_COMMANDS`` lists their ``register`` functions."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    SubParsers = argparse._SubParsersAction[argparse.ArgumentParser]
else:
    SubParsers = argparse._SubParsersAction
Register = Callable[[SubParsers], None]


def _core() -> list[Register]:
    from station.commands import (
        calibrate,
        camera,
        measure,
        run,
        scale_calibration,
        sessions,
        sweep,
        table,
        validate,
    )

    return [
        measure.register,
        validate.register,
        sweep.register,
        camera.register,
        table.register,
        run.register,
        sessions.register,
        calibrate.register,
        scale_calibration.register,
    ]


CORE_COMMANDS: list[Register] = _core()
