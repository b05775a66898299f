"""One session at a time per station, across processes: locks on ``DATA_DIR/station.lock``.

Two byte-range locks of the open file description (Linux OFD locks, ``F_OFD_SETLK``) on that file:

* byte 0, **the station**: held from the start of a session until its outcome is known. Its holder
  writes its pid, host and session id into the file; a second taker gets :class:`SessionLockError`
  naming it.
* byte 1, **the record's last word**: held a little longer, until the session's final state is
  recorded. The station is released first (:meth:`StationLock.release`), so that whoever sees the final
  state can start the next session at once; the next holder waits for byte 1 before it reconciles the
  record (marks sessions left active by a dead process as interrupted), so a session that is only
  finishing is never taken for a dead one.

Who holds the station is asked with ``F_OFD_GETLK``, which tests a lock without taking it: listing
sessions or reading the station's state never makes a session start fail, creates no file and needs
no write access. The kernel drops OFD locks when the last descriptor of their open file is closed,
also when the process dies (even by SIGKILL): a dead owner's lock is free without any stale-lock
clean-up, and the file's text is then only history. The descriptor is close-on-exec (a program the
holder starts does not inherit the lock; a child made by a bare ``fork`` would: start workers with
``spawn`` or ``forkserver``).
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import socket
import struct
import time
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from station.record._errors import RecordError, SessionLockError

LOCK_FILE = "station.lock"
STATION_BYTE = 0
FINISHING_BYTE = 1
FINISH_WAIT_S = 60.0
"""The longest a new holder waits for the previous session to record its final state."""

# struct flock on 64-bit Linux: short l_type, short l_whence, off_t l_start, off_t l_len, pid_t l_pid
_FLOCK = "hhqqi4x"
_EMPTY_HOLDER: dict[str, Any] = {"pid": None, "host": None, "session_id": None}
# The holder's text, padded to a fixed size and blanked on release: rewritten in place, never truncated
# (a truncation makes the file system flush, 0.1 s a time on ext4) and never fsynced (after a crash the
# lock is free whatever the text says).
_HOLDER_BYTES = 512


def _lock(fd: int, command: int, kind: int, byte: int) -> int:
    """One ``fcntl`` lock call on one byte; the lock type the kernel answers (GETLK: ``F_UNLCK`` = free)."""
    answer = fcntl.fcntl(fd, command, struct.pack(_FLOCK, kind, os.SEEK_SET, byte, 1, 0))
    kind_now: int = struct.unpack(_FLOCK, answer)[0]
    return kind_now


def _try_lock(fd: int, byte: int) -> bool:
    try:
        _lock(fd, fcntl.F_OFD_SETLK, fcntl.F_WRLCK, byte)
    except OSError as exc:
        if exc.errno in (errno.EAGAIN, errno.EACCES):
            return False
        raise
    return True


def _is_locked(fd: int, byte: int) -> bool:
    return _lock(fd, fcntl.F_OFD_GETLK, fcntl.F_WRLCK, byte) != fcntl.F_UNLCK


def _read_holder(fd: int) -> dict[str, Any]:
    text = os.pread(fd, _HOLDER_BYTES, 0).decode("utf-8", "replace")
    try:
        holder = json.loads(text)
    except ValueError:
        holder = None
    if not isinstance(holder, dict):  # the holder is still writing it
        return dict(_EMPTY_HOLDER)
    return holder


class StationLock:
    """The station, held (see the module notes); ``holder`` is what the lock file says."""

    def __init__(self, fd: int, path: Path, holder: dict[str, Any]) -> None:
        self._fd = fd
        self.path = path
        self.holder = holder
        self.released = False

    def release(self) -> None:
        """Free the station for the next session (idempotent); the record's last word (byte 1) stays
        held until the ``station_lock`` block ends."""
        if self.released:
            return
        self.released = True
        os.pwrite(self._fd, b" " * _HOLDER_BYTES, 0)
        _lock(self._fd, fcntl.F_OFD_SETLK, fcntl.F_UNLCK, STATION_BYTE)


def _wait_for_last_word(fd: int, path: Path, timeout_s: float) -> None:
    """Take byte 1: wait (polling, bounded) while the previous session records its final state."""
    deadline = time.monotonic() + timeout_s
    delay = 0.001
    while not _try_lock(fd, FINISHING_BYTE):
        if time.monotonic() > deadline:
            raise RecordError(
                f"the previous session still records its final state after {timeout_s:.0f} s (lock "
                f"{path}): check the database server, then start again"
            )
        time.sleep(delay)
        delay = min(delay * 2, 0.05)


@contextlib.contextmanager
def station_lock(
    data_dir: Path, session_id: str, *, finish_wait_s: float = FINISH_WAIT_S
) -> Iterator[StationLock]:
    """Hold the station for ``session_id``; a SessionLockError naming the holder if it is taken.

    Leaving the block frees everything; :meth:`StationLock.release` frees the station earlier.
    """
    data_dir.mkdir(parents=True, exist_ok=True)
    path = data_dir / LOCK_FILE
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
    try:
        if not _try_lock(fd, STATION_BYTE):
            raise SessionLockError(str(path), _read_holder(fd))
        holder = {
            "pid": os.getpid(),
            "host": socket.gethostname(),
            "session_id": session_id,
            "since": datetime.now(UTC).isoformat(),
        }
        held = StationLock(fd, path, holder)
        try:
            os.pwrite(fd, json.dumps(holder).encode()[:_HOLDER_BYTES].ljust(_HOLDER_BYTES), 0)
            _wait_for_last_word(fd, path, finish_wait_s)
            yield held
        finally:
            held.release()
    finally:
        os.close(fd)  # releases byte 1 (and byte 0 if still held)


def _probe(data_dir: Path, byte: int) -> tuple[bool, dict[str, Any]]:
    try:
        fd = os.open(data_dir / LOCK_FILE, os.O_RDONLY | os.O_CLOEXEC | os.O_NOFOLLOW)
    except (FileNotFoundError, NotADirectoryError):
        return False, {}
    try:
        if not _is_locked(fd, byte):
            return False, {}
        return True, _read_holder(fd)
    finally:
        os.close(fd)


def lock_holder(data_dir: Path) -> dict[str, Any] | None:
    """Who holds the station (``pid``, ``host``, ``session_id``, ``since``), or None when it is free.

    Takes no lock and writes nothing (see the module notes)."""
    held, holder = _probe(data_dir, STATION_BYTE)
    return holder if held else None


def station_in_use(data_dir: Path) -> bool:
    """Whether a session's process is alive on this station: holding it, or recording a final state.
    Takes no lock and writes nothing."""
    return _probe(data_dir, STATION_BYTE)[0] or _probe(data_dir, FINISHING_BYTE)[0]
