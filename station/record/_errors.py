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
        if holder.get("pid") is None:  # the holder has not written its name yet
            who = "another session is starting"
        else:
            who = (
                f"session {holder.get('session_id')!r} runs in process {holder.get('pid')} on host "
                f"{holder.get('host')!r}"
            )
        super().__init__(
            f"the station is busy: {who} (lock {lock_path}); wait for it to finish or stop it first"
        )
        self.lock_path = lock_path
        self.holder = holder


class NoRecordError(RecordError):
    """A read-only command found no record in the data directory: nothing was ever recorded there."""

    def __init__(self, data_dir: object) -> None:
        super().__init__(
            f"no record in {data_dir}: nothing has been recorded there yet (check --data or $STATION_DATA)"
        )
        self.data_dir = data_dir


IMPORT_HINT = (
    "nothing was imported: import a folder or zip written by `station export` (or export.zip), unchanged"
)


class ImportRefusedError(RecordError):
    """An export folder or archive is refused before anything is written; ``field`` names what is wrong."""

    code = "import_refused"

    def __init__(self, field: str, reason: str, hint: str = IMPORT_HINT) -> None:
        text = f"{field}: {reason}; {hint}" if hint else f"{field}: {reason}"
        super().__init__(" ".join(text.split()))  # one line, whatever the reason holds
        self.field = field
        self.reason = reason


class ArchiveRefusedError(ImportRefusedError):
    """The zip archive itself is refused (not a zip, a bad entry, over a cap)."""

    code = "bad_archive"


def error_of(exc: sa.exc.DBAPIError) -> type[RecordError]:
    """The record's exception type for a database error: :class:`RecordUnavailableError` when the
    database cannot be reached (an operational or interface error: a stopped server, a lost
    connection, an unreadable file), else :class:`RecordError`."""
    if isinstance(exc, sa.exc.OperationalError | sa.exc.InterfaceError) or exc.connection_invalidated:
        return RecordUnavailableError
    return RecordError
