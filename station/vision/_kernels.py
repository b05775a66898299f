"""Which implementation runs the hot loops: the compiled kernels or the numpy reference (issue 12).

The compiled kernels (``_ckernels.c``, a small C extension built by the normal install; plain C on
the buffer protocol) do what the numpy code beside each call does, element for element, in one call
instead of a few hundred numpy calls. The numpy code stays the tested reference
(``tests/vision/test_kernels.py``: both give the same results within 1e-9 px on the benchmark
images). The choice:

* ``STATION_VISION_KERNELS=numpy`` in the environment (read at import), or ``use_kernels("numpy")``:
  the numpy reference everywhere;
* ``auto`` (the default): the compiled kernels when the extension was built, else numpy;
* ``c``: the compiled kernels, an ImportError if the extension is missing.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Literal

Choice = Literal["auto", "c", "numpy"]
ENV = "STATION_VISION_KERNELS"

_built: ModuleType | None
try:
    from station.vision import _ckernels as _built
except ImportError as exc:  # not built (no compiler at install time): the numpy reference runs
    _built = None
    _missing: str = str(exc)
else:
    _missing = ""

_active: ModuleType | None = None


def available() -> bool:
    """Whether the compiled kernels were built."""
    return _built is not None


def use_kernels(choice: str) -> None:
    """Select ``auto``, ``c`` or ``numpy`` for every measurement from now on (process-wide)."""
    global _active
    if choice not in ("auto", "c", "numpy"):
        raise ValueError(f"{ENV}={choice!r}: expected auto, c or numpy")
    if choice == "c" and _built is None:
        raise ImportError(f"{ENV}=c but the compiled kernels were not built ({_missing}); reinstall")
    _active = None if choice == "numpy" else _built


@contextmanager
def kernels(choice: str) -> Iterator[None]:
    """``use_kernels(choice)`` within a ``with`` block, the previous choice restored after it."""
    global _active
    before = _active
    use_kernels(choice)
    try:
        yield
    finally:
        _active = before


def compiled() -> ModuleType | None:
    """The compiled kernels' module when they are selected, else None (run the numpy reference)."""
    return _active


use_kernels(os.environ.get(ENV, "auto").strip().lower() or "auto")
