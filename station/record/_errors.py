"""The record's exceptions: every one says what went wrong, where, and what to do."""

from __future__ import annotations

import sqlalchemy as sa


class RecordError(RuntimeError):
    """The record cannot do what was asked (bad prefix, changed image file, duplicate import ...)."""


class RecordUnavailableError(RecordError):
    """The database cannot be reached (its server stopped, the connection lost, the file unreadable);
    nothing was read or written: retry once it is back."""


class RecordNotFoundError(RecordError):
    """No session with that id (or unique id prefix) in the record."""

    def __init__(self, id_or_prefix: str, url: str) -> None:
        super().__init__(f"no session {id_or_prefix!r} in the record at {url}; `station sessions` lists them")
        self.id_or_prefix = id_or_prefix
        self.url = url


class RecordWriteError(RecordError):
    """An image or file could not be written (disk full, permissions ...); nothing was recorded."""

    def __init__(self, path: str, error: OSError) -> None:
        reason = error.strerror or str(error)
        super().__init__(
            f"cannot write {path}: {reason} (errno {error.errno}); nothing of it was recorded: "
            "free space or fix permissions in the data directory and resume the session"
        )
        self.path = path
        self.errno = error.errno


class SessionLockError(RecordError):
    """Another session holds the station: one session at a time per station."""

    def __init__(self, lock_path: str, holder: dict[str, object]) -> None:
        super().__init__(
            f"the station is busy: session {holder.get('session_id')!r} runs in process "
            f"{holder.get('pid')} on host {holder.get('host')!r} (lock {lock_path}); wait for it to "
            "finish or stop it first"
        )
        self.lock_path = lock_path
        self.holder = holder


def error_of(exc: sa.exc.DBAPIError) -> type[RecordError]:
    """The record's exception type for a database error: :class:`RecordUnavailableError` when the
    database cannot be reached (an operational or interface error: a stopped server, a lost
    connection, an unreadable file), else :class:`RecordError`."""
    if isinstance(exc, sa.exc.OperationalError | sa.exc.InterfaceError) or exc.connection_invalidated:
        return RecordUnavailableError
    return RecordError
