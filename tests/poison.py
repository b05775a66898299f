"""A frame that kills the process measuring it, as the kernel's OOM killer or a crashing decoder would.

Injected as ``measure_one`` into the compute backends; it must be importable where the task runs (a
pool process, a Dask worker) and cheap to import there, so this module imports nothing else of the tests.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path

from station.batch import AnyParams, FileResult, measure_file
from station.imageio import ImageLimits


def dies_on_poison(path: str, params: AnyParams, limits: ImageLimits | None) -> FileResult:
    """``measure_file``, except that files named ``poison*`` SIGKILL the process measuring them."""
    if Path(path).name.startswith("poison"):
        os.kill(os.getpid(), signal.SIGKILL)
    return measure_file(path, params, limits)
