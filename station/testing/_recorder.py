"""What every fake shares: a record of its calls (``calls``), failures on request (``fail_on``) and
the assertion helpers, and the one lifecycle (``connect``/``close``)."""

from __future__ import annotations

import threading
from typing import Any

import numpy as np
import numpy.typing as npt

from station.devices import (
    DeviceIdentity,
)

FloatArray = npt.NDArray[np.float64]


class _Recorder:
    """Call log and scripted failures shared by the fakes."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self._failures: dict[str, list[tuple[int, BaseException]]] = {}
        self._counts: dict[str, int] = {}
        self._rec_lock = threading.Lock()

    def fail_on(self, method: str, exc: BaseException, *, nth: int = 1) -> None:
        """Raise ``exc`` on the ``nth`` call of ``method`` from now on (1 = the next call)."""
        with self._rec_lock:
            done = self._counts.get(method, 0)
            self._failures.setdefault(method, []).append((done + nth, exc))

    def _call(self, method: str, *args: Any) -> None:
        with self._rec_lock:
            self.calls.append((method, args))
            n = self._counts[method] = self._counts.get(method, 0) + 1
            for i, (when, exc) in enumerate(self._failures.get(method, [])):
                if when == n:
                    del self._failures[method][i]
                    raise exc

    def calls_of(self, method: str) -> list[tuple[Any, ...]]:
        return [args for name, args in self.calls if name == method]

    def assert_called(self, method: str, times: int | None = None) -> None:
        n = len(self.calls_of(method))
        if (times is None and n == 0) or (times is not None and n != times):
            want = "at least once" if times is None else f"{times} time(s)"
            raise AssertionError(f"{type(self).__name__}.{method} called {n} time(s), expected {want}")

    def assert_not_called(self, method: str) -> None:
        self.assert_called(method, 0)


class _FakeDevice(_Recorder):
    """The lifecycle every fake shares: ``connect``/``close`` recorded, ``identity`` from ``MODEL``."""

    MODEL = "fake device"

    def __init__(self) -> None:
        super().__init__()
        self.connected = False

    def connect(self) -> None:
        self._call("connect")
        self.connected = True

    def close(self) -> None:
        self._call("close")
        self.connected = False

    def identity(self) -> DeviceIdentity:
        return DeviceIdentity(model=self.MODEL, serial="fake-1", port="in-process", firmware=None)


__all__ = [
    "_FakeDevice",
    "_Recorder",
]
