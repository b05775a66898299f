"""The service side: :class:`WorkerClient` starts the station worker process, calls it and mirrors
what it reports (see the package's notes)."""

from __future__ import annotations

import contextlib
import itertools
import logging
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future
from multiprocessing.connection import Pipe
from typing import Any

from station.prompts import Prompt
from station.record import (
    EventRow,
)
from station.worker._common import START_TIMEOUT_S, RunnerStatus, StationInfo, WorkerError, WorkerSpec
from station.worker._transport import _emit_log, _Pipe, _unpack_exception

log = logging.getLogger(__name__)


# --------------------------------------------------------------------------- the front end's side


class WorkerClient:
    """The front end's handle on the worker: calls, and the mirror of what the worker reports.

    ``on_event(event)`` is called from the handle's reader thread for every event, after ``status``
    has been updated with it; ``on_ended(status)`` when the worker's session failed in a way its runner
    could not record (``status.error`` says why; the record follows once it can be reached).
    """

    def __init__(
        self,
        spec: WorkerSpec,
        *,
        on_event: Callable[[EventRow], None],
        on_exit: Callable[[], None] | None = None,
        on_ended: Callable[[RunnerStatus], None] | None = None,
        start_timeout_s: float = START_TIMEOUT_S,
    ) -> None:
        here, there = Pipe()
        self._on_event = on_event
        self._on_exit = on_exit
        self._on_ended = on_ended
        self._pipe = _Pipe(here)
        self._calls: dict[int, Future[Any]] = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._gone: str | None = None
        self._closing = False
        self.status: RunnerStatus | None = None
        self.prompt: Prompt | None = None
        # a fresh interpreter (not multiprocessing's spawn, which imports the caller's main module again):
        # it inherits the environment and the standard streams; the pipe's other end is its only extra fd
        fd = there.fileno()
        self._process = subprocess.Popen(
            [sys.executable, "-c", "import station.worker as w; w.main()", str(fd)], pass_fds=(fd,)
        )
        there.close()
        try:
            self._pipe.send(("start", list(sys.path), spec))
            deadline = time.monotonic() + start_timeout_s
            while True:
                if not here.poll(max(0.0, deadline - time.monotonic())):
                    raise WorkerError(f"the station worker did not start within {start_timeout_s:.0f} s")
                first = here.recv()
                if first[0] != "log":
                    break
                _emit_log(first[1])
        except (EOFError, OSError) as exc:
            self._kill()
            raise WorkerError(
                f"the station worker exited while starting (exit code {self._process.poll()}): {exc}"
            ) from exc
        except BaseException:
            self._kill()
            raise
        if first[0] == "failed":
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(10)
            self._kill()
            raise _unpack_exception(first[1])
        self.info: StationInfo = first[1]
        self._reader = threading.Thread(target=self._read, name="station-worker-reader", daemon=True)
        self._reader.start()

    @property
    def alive(self) -> bool:
        return self._gone is None

    @property
    def pid(self) -> int:
        """The worker's process id."""
        return self._process.pid

    def _kill(self) -> None:
        if self._process.poll() is None:
            self._process.kill()
            self._process.wait(10)
        self._pipe.conn.close()

    def _read(self) -> None:
        conn = self._pipe.conn
        try:
            while True:
                message = conn.recv()
                kind = message[0]
                if kind == "event":
                    self.status = message[2]
                    self._on_event(message[1])
                elif kind == "ended":  # a failure the record could not take (yet): see RunnerStatus.error
                    self.status = message[1]
                    if self._on_ended is not None:
                        self._on_ended(message[1])
                elif kind == "prompt":
                    shown, pid = message[1], message[2]
                    if shown is not None:
                        self.prompt = shown
                    elif self.prompt is not None and self.prompt.id == pid:
                        self.prompt = None
                elif kind == "reply":
                    future = self._calls.pop(message[1], None)
                    if future is not None:
                        if message[2]:
                            future.set_result(message[3])
                        else:
                            future.set_exception(_unpack_exception(message[3]))
                elif kind == "log":
                    _emit_log(message[1])
        except (EOFError, OSError):
            pass
        except Exception:
            log.exception("the station worker's reader failed")
        if not self._closing:
            # the pipe closes while the process exits; its flocks (the station lock) are gone once it has
            with contextlib.suppress(subprocess.TimeoutExpired):
                self._process.wait(30)
        with self._lock:
            self._gone = (
                "the service is shutting down"
                if self._closing
                else f"the station worker process ended (exit code {self._process.poll()}); restart the "
                "service (its session, if any, shows as interrupted)"
            )
            calls, self._calls = self._calls, {}
        self.prompt = None
        for future in calls.values():
            future.set_exception(WorkerError(self._gone))
        if not self._closing:
            log.error("%s", self._gone)
            if self._on_exit is not None:
                self._on_exit()

    def call(self, method: str, *args: Any, timeout_s: float | None = None, **kwargs: Any) -> Any:
        """``SessionHost.rpc_<method>(*args, **kwargs)`` in the worker; its exception is raised here."""
        future: Future[Any] = Future()
        with self._lock:
            if self._gone is not None:
                raise WorkerError(self._gone)
            rid = next(self._ids)
            self._calls[rid] = future
            try:
                self._pipe.send(("call", rid, method, args, kwargs))
            except (OSError, ValueError) as exc:
                self._calls.pop(rid, None)
                raise WorkerError(f"the station worker cannot be reached: {exc}") from exc
        return future.result(timeout_s)

    def close(self, timeout_s: float = 30.0) -> None:
        """Shut the worker down in order (its session interrupted, devices closed) and wait for it."""
        if self._closing:
            return
        if self.alive:
            with contextlib.suppress(WorkerError, TimeoutError, OSError):
                self.call("shutdown", timeout_s, timeout_s=timeout_s + 10)
        self._closing = True
        with contextlib.suppress(OSError, ValueError):
            self._pipe.send(("exit",))
        try:
            self._process.wait(timeout_s)
        except subprocess.TimeoutExpired:
            log.error("the station worker did not exit; terminating it")
            self._process.terminate()
            self._process.wait(10)
        self._reader.join(10)  # the worker's end closed with it: the reader has read to the end
        with contextlib.suppress(OSError):
            self._pipe.conn.close()
