"""The worker process's entry point and life: its priority, SIGTERM, and serving the service's calls
over the pipe until it closes."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading
import traceback
from multiprocessing.connection import Connection
from typing import Any

from station.runner import (
    SessionError,
)
from station.worker._common import WorkerSpec
from station.worker._transport import _pack_exception, _Pipe, _PipeLogHandler
from station.worker.host import SessionHost

log = logging.getLogger(__name__)


class _Terminated(BaseException):
    """SIGTERM in the worker: shut down in order."""


def _on_sigterm(signum: int, frame: Any) -> None:
    raise _Terminated


def _prefer(nice: int) -> None:
    """Run at ``nice`` when it is above the current priority and allowed; say so when it is not."""
    current = os.getpriority(os.PRIO_PROCESS, 0)
    if nice >= current:
        return
    try:
        os.setpriority(os.PRIO_PROCESS, 0, nice)
    except PermissionError:
        log.info(
            "the station worker runs at nice %d, not %d: no right to raise its priority (root or "
            "CAP_SYS_NICE); under CPU load its cycles may then stretch",
            current,
            nice,
        )


def worker_main(conn: Connection, spec: WorkerSpec) -> None:
    """The worker process: build the station, then serve the front end's calls until the pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the front end, which shuts us down
    signal.signal(signal.SIGTERM, _on_sigterm)
    pipe = _Pipe(conn)
    root = logging.getLogger()
    for handler in list(root.handlers):
        root.removeHandler(handler)
    root.addHandler(_PipeLogHandler(pipe.send))
    root.setLevel(spec.log_level)
    _prefer(spec.nice)
    try:
        host = SessionHost(spec, pipe.send)
    except BaseException as exc:  # noqa: BLE001 - reported to the front end, which raises it
        pipe.send(("failed", _pack_exception(exc), traceback.format_exc()))
        return
    try:
        pipe.send(("ready", host.info()))
        while True:
            message = conn.recv()
            if message[0] == "exit":
                break
            if message[0] == "call":
                threading.Thread(
                    target=_serve_call, args=(host, pipe, *message[1:]), name=f"rpc-{message[2]}", daemon=True
                ).start()
    except (EOFError, OSError):
        why = "the service went away"
    except _Terminated:
        why = "the station worker was terminated (SIGTERM)"
    else:
        why = "the service shut down"
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the shutdown below is the answer to it
    with contextlib.suppress(BaseException):
        host.shutdown(why=why)


def main() -> None:
    """The worker's entry point: ``python -c "import station.worker as w; w.main()" FD``, FD being its
    end of the pipe; the first message is the front end's ``sys.path`` and the :class:`WorkerSpec`."""
    conn = Connection(int(sys.argv[1]))
    try:
        kind, path, spec = conn.recv()
    except EOFError:
        return
    if kind != "start":
        raise SystemExit(f"station worker: expected the start message, got {kind!r}")
    sys.path[:] = path  # the front end's modules (a test's or a benchmark's hooks) import here too
    worker_main(conn, spec)


def _serve_call(
    host: SessionHost, pipe: _Pipe, rid: int, method: str, args: tuple[Any, ...], kwargs: dict[str, Any]
) -> None:
    try:
        value = getattr(host, f"rpc_{method}")(*args, **kwargs)
    except BaseException as exc:  # noqa: BLE001 - the caller gets it
        reply: tuple[Any, ...] = ("reply", rid, False, _pack_exception(exc))
    else:
        reply = ("reply", rid, True, value)
    try:
        pipe.send(reply)
    except (OSError, ValueError):
        return  # the front end has gone
    except Exception as exc:  # noqa: BLE001 - a value that does not pickle
        pipe.send(("reply", rid, False, _pack_exception(SessionError(f"{method}: {exc}"))))
