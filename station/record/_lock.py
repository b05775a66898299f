"""One session at a time per station, across processes: an flock on ``DATA_DIR/station.lock``.

The holder writes its pid, host and session id into the file. The kernel drops an flock when its
process dies (even by SIGKILL), so a dead owner's lock is free without any stale-lock clean-up; the
file's text is then only history. The descriptor is close-on-exec: a program the holder starts does
not inherit the lock (a child made by a bare ``fork`` would: start workers with ``spawn`` or
``forkserver``).
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from station.record._errors import SessionLockError

LOCK_FILE = "station.lock"


def _read_holder(fd: int) -> dict[str, Any]:
    os.lseek(fd, 0, os.SEEK_SET)
    text = os.read(fd, 4096).decode("utf-8", "replace")
    try:
        holder = json.loads(text)
    except ValueError:
        holder = None
    if not isinstance(holder, dict):  # the holder is still writing it
        return {"pid": None, "host": None, "session_id": None}
    return holder


@contextlib.contextmanager
def station_lock(data_dir: Path, session_id: str) -> Iterator[dict[str, Any]]:
    """Hold the station for ``session_id``; a SessionLockError naming the holder if it is taken."""
    data_dir.mkdir(parents=True, exist_ok=True)
    path = data_dir / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise SessionLockError(str(path), _read_holder(fd)) from None
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "session_id": session_id,
            "since": datetime.now(UTC).isoformat(),
        }
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(holder).encode(), 0)
        os.fsync(fd)
        try:
            yield holder
        finally:
            os.ftruncate(fd, 0)
    finally:
        os.close(fd)  # releases the flock


def lock_holder(data_dir: Path) -> dict[str, Any] | None:
    """Who holds the station (``pid``, ``host``, ``session_id``, ``since``), or None when it is free."""
    path = data_dir / LOCK_FILE
    try:
        fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
    except FileNotFoundError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return _read_holder(fd)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)
