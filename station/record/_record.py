"""The record: sessions, their steps, events, captures and measurements, in one database.

Images live as PNG files under ``DATA_DIR/images/<session>/``; the database holds their paths and
sha256. Every method is one short transaction, so the runner, the web API and ``station sessions``
can share one record from several threads and processes; nothing image-sized is kept in memory.
"""

from __future__ import annotations

import contextlib
import re
import uuid
from collections.abc import Callable, Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, BinaryIO, Self

import sqlalchemy as sa

from station.record import _export
from station.record._engine import BEGIN_OPTION, open_engine, reason
from station.record._errors import RecordError, RecordNotFoundError, error_of
from station.record._format import SESSION_ID
from station.record._frames import FramesMixin
from station.record._import import import_export
from station.record._json import json_object
from station.record._rows import (
    STEP_STATES,
    EventRow,
    SessionRow,
    StepRow,
    event_row,
    session_row,
    step_row,
)
from station.record._schema import events, new_id, sessions, steps
from station.record._sources import ArchiveLimits, FolderSource, ZipSource, open_source

Clock = Callable[[], datetime]
_HEX_PREFIX = re.compile(r"[0-9a-f]{4,12}")
MIN_PREFIX = 4


def _utc_now() -> datetime:
    return datetime.now(UTC)


def random_session_id() -> str:
    """12 lowercase hex digits from a random UUID (about 2.8e14 values)."""
    return uuid.uuid4().hex[:12]


class Record(FramesMixin):
    """The station's durable record (see the package notes).

    Parameters
    ----------
    data_dir
        Directory of the images (and of the SQLite file by default); created if missing.
    url
        A SQLAlchemy database URL; None for SQLite in ``data_dir/record.sqlite``.
    clock
        Returns the current aware time (UTC); injected by tests.
    make_id
        Returns a new session id (12 lowercase hex digits); injected by tests.
    busy_timeout_s
        SQLite only: how long a writer waits for another writer before failing.
    read_only
        Open for reading only (``station sessions``, ``report``, ``export``): nothing is created,
        migrated or written, and it works on a full disk or a read-only directory; a missing data
        directory or record is a :class:`NoRecordError`.
    """

    def __init__(
        self,
        data_dir: Path,
        url: str | None = None,
        *,
        clock: Clock = _utc_now,
        make_id: Callable[[], str] = random_session_id,
        busy_timeout_s: float = 30.0,
        read_only: bool = False,
    ) -> None:
        self._data_dir = Path(data_dir)
        self._read_only = read_only
        self._clock = clock
        self._make_id = make_id
        self._engine, self._url = open_engine(
            self._data_dir, url, busy_timeout_s=busy_timeout_s, read_only=read_only
        )

    # -- lifecycle -------------------------------------------------------------------------------
    @property
    def data_dir(self) -> Path:
        return self._data_dir

    @property
    def url(self) -> str:
        """The database URL with any password hidden (user part and query)."""
        return self._url

    @property
    def read_only(self) -> bool:
        return self._read_only

    @property
    def engine(self) -> sa.Engine:
        """The SQLAlchemy engine (for tests and tools; use the methods otherwise)."""
        return self._engine

    def close(self) -> None:
        self._engine.dispose()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"Record({str(self._data_dir)!r}, url={self.url!r})"

    @contextlib.contextmanager
    def _write(self) -> Iterator[sa.Connection]:
        """One write transaction; a database failure (disk full, lost server ...) is a RecordError."""
        if self._read_only:
            raise RecordError(f"the record at {self.url} was opened read-only: this command does not write")
        try:
            with self._engine.connect() as conn:
                conn = conn.execution_options(**{BEGIN_OPTION: "IMMEDIATE"})
                with conn.begin():
                    yield conn
        except sa.exc.DBAPIError as exc:
            raise error_of(exc)(
                f"cannot write to the record at {self.url}: {reason(exc, self._engine.url)}; nothing of "
                "this change was recorded (check free space and the database server)"
            ) from exc

    @contextlib.contextmanager
    def _read(self) -> Iterator[sa.Connection]:
        try:
            with self._engine.connect() as conn:
                yield conn
        except sa.exc.DBAPIError as exc:
            raise error_of(exc)(
                f"cannot read the record at {self.url}: {reason(exc, self._engine.url)}"
            ) from exc

    def _now(self) -> datetime:
        now = self._clock()
        if now.tzinfo is None:
            raise RecordError("the record's clock returned a naive datetime; it must be aware (UTC)")
        return now.astimezone(UTC)

    def _require_session(self, conn: sa.Connection, session_id: str, *, lock: bool = False) -> None:
        query = sa.select(sessions.c.id).where(sessions.c.id == session_id)
        if lock:
            query = query.with_for_update()
        if conn.execute(query).first() is None:
            raise RecordNotFoundError(session_id, self.url)

    # -- sessions --------------------------------------------------------------------------------
    def create_session(
        self,
        kind: str,
        *,
        params: Mapping[str, Any],
        config: Mapping[str, Any],
        identities: Mapping[str, Any],
        software: Mapping[str, Any],
        parent_id: str | None = None,
        station: str = "default",
    ) -> SessionRow:
        """A new session in state ``idle`` with a fresh 12-hex-digit id."""
        if not kind:
            raise ValueError("kind must name the plan (validation, repeatability ...), not be empty")
        session_id = self._make_id()
        if not SESSION_ID.fullmatch(session_id):
            raise RecordError(f"session id {session_id!r} is not 12 lowercase hex digits")
        now = self._now()
        row = SessionRow(
            id=session_id,
            kind=kind,
            state="idle",
            created_at=now,
            updated_at=now,
            params=json_object(params, "params"),
            config=json_object(config, "config"),
            identities=json_object(identities, "identities"),
            software=json_object(software, "software"),
            results=None,
            error=None,
            parent_id=parent_id,
            station=station,
        )
        with self._write() as conn:
            if parent_id is not None:
                self._require_session(conn, parent_id)
            conn.execute(sessions.insert().values(**row.__dict__))
        return row

    def get_session(self, id_or_prefix: str) -> SessionRow:
        """The session with this id, or with this unique id prefix of at least 4 characters."""
        key = id_or_prefix.strip().lower()
        if len(key) < MIN_PREFIX and _HEX_PREFIX.fullmatch(key.ljust(MIN_PREFIX, "0")):
            raise RecordError(
                f"session id prefix {id_or_prefix!r} is too short: give at least {MIN_PREFIX} characters"
            )
        if not _HEX_PREFIX.fullmatch(key):
            raise RecordNotFoundError(id_or_prefix, self.url)
        with self._read() as conn:
            if len(key) == 12:
                rows = conn.execute(sa.select(sessions).where(sessions.c.id == key)).all()
            else:
                query = sa.select(sessions).where(sessions.c.id.startswith(key, autoescape=True))
                rows = conn.execute(query.order_by(sessions.c.id).limit(10)).all()
        if not rows:
            raise RecordNotFoundError(id_or_prefix, self.url)
        if len(rows) > 1:
            names = ", ".join(r.id[:40] for r in rows)
            raise RecordError(
                f"session prefix {id_or_prefix!r} is ambiguous: it matches {names}; give more characters"
            )
        if not SESSION_ID.fullmatch(rows[0].id):  # a record altered by hand, or an old import
            raise RecordError(
                f"the record at {self.url} holds a session whose id {rows[0].id[:40]!r} is not 12 hex "
                "digits: it was not written by the station; remove that session from the record"
            )
        return session_row(rows[0])

    def list_sessions(self, kind: str | None = None) -> list[SessionRow]:
        """Every session (or those of one kind), newest first."""
        query = sa.select(sessions).order_by(sessions.c.created_at.desc(), sessions.c.id.desc())
        if kind is not None:
            query = query.where(sessions.c.kind == kind)
        with self._read() as conn:
            return [session_row(r) for r in conn.execute(query)]

    def set_state(self, session_id: str, state: str, *, error: str | None = None) -> None:
        """Set the session's state and its error text (None clears it)."""
        if not state:
            raise ValueError("state must be a runner state name, not empty")
        self._update_session(session_id, state=state, error=error)

    def set_identities(self, session_id: str, identities: Mapping[str, Any]) -> None:
        """Replace the session's device identities: what the devices report once connected (a session
        is created before its devices connect, with what the configuration alone says)."""
        self._update_session(session_id, identities=json_object(identities, "identities"))

    def set_results(self, session_id: str, results: Mapping[str, Any]) -> None:
        """Store the session's results (replacing any earlier ones)."""
        self._update_session(session_id, results=json_object(results, "results"))

    def _update_session(self, session_id: str, **values: Any) -> None:
        """Set columns of one session's row (and its ``updated_at``); it must exist."""
        with self._write() as conn:
            done = conn.execute(
                sessions.update().where(sessions.c.id == session_id).values(**values, updated_at=self._now())
            )
            if done.rowcount == 0:
                raise RecordNotFoundError(session_id, self.url)

    # -- events ----------------------------------------------------------------------------------
    def add_event(self, session_id: str, type: str, data: Mapping[str, Any]) -> EventRow:
        """Append an event; its ``seq`` is the session's next, its ``id`` the station-wide next.

        On SQLite commits are serialised, so ids appear to readers in increasing order and polling
        with ``events(after_id=...)`` misses none. On a server shared by several stations, ids are
        drawn when rows are inserted and two stations' commits may land out of order: a reader that
        follows several sessions there should poll per session and use ``seq``.
        """
        value = json_object(data, "data")
        now = self._now()
        with self._write() as conn:
            self._require_session(conn, session_id, lock=True)
            last = conn.execute(
                sa.select(sa.func.max(events.c.seq)).where(events.c.session_id == session_id)
            ).scalar_one()
            seq = (last or 0) + 1
            done = conn.execute(
                events.insert().values(session_id=session_id, seq=seq, time=now, type=type, data=value)
            )
            event_id = new_id(done)
        return EventRow(id=event_id, session_id=session_id, seq=seq, time=now, type=type, data=value)

    def last_event(self, type_: str) -> EventRow | None:
        """The station's newest event of type ``type_`` (highest id, whatever session), or None: one
        index seek (``ix_events_type_id``), however many sessions and events the record holds."""
        query = sa.select(events).where(events.c.type == type_).order_by(events.c.id.desc()).limit(1)
        with self._read() as conn:
            row = conn.execute(query).first()
        return None if row is None else event_row(row)

    def events(
        self, session_id: str | None = None, *, after_id: int = 0, after_seq: int = 0, limit: int = 1000
    ) -> list[EventRow]:
        """Events with ``id > after_id`` (of one session or all; with a session also ``seq > after_seq``,
        how a stream resumes after its last sequence number), ascending id, at most ``limit``."""
        query = sa.select(events).where(events.c.id > after_id).order_by(events.c.id).limit(limit)
        if session_id is not None:
            query = query.where(events.c.session_id == session_id)
            if after_seq:
                query = query.where(events.c.seq > after_seq)
        with self._read() as conn:
            return [event_row(r) for r in conn.execute(query)]

    # -- steps -----------------------------------------------------------------------------------
    def begin_step(
        self, session_id: str, index: int, name: str, data: Mapping[str, Any] | None = None
    ) -> None:
        """Mark step ``index`` started.

        Re-beginning a step that exists (resume after an interruption) resets it: its state goes back
        to ``started``. The captures and measurements its interrupted attempt recorded are kept
        (nothing captured is ever lost); the runner numbers a new attempt's frames after them and
        analyses the attempt that completed.
        """
        value = json_object(data or {}, "data")
        now = self._now()
        key = (steps.c.session_id == session_id) & (steps.c.step_index == index)
        with self._write() as conn:
            self._require_session(conn, session_id)
            exists = conn.execute(sa.select(steps.c.step_index).where(key)).first() is not None
            if exists:
                conn.execute(
                    steps.update()
                    .where(key)
                    .values(name=name, state="started", data=value, started_at=now, finished_at=None)
                )
            else:
                conn.execute(
                    steps.insert().values(
                        session_id=session_id,
                        step_index=index,
                        name=name,
                        state="started",
                        data=value,
                        started_at=now,
                        finished_at=None,
                    )
                )

    def finish_step(
        self,
        session_id: str,
        index: int,
        *,
        data: Mapping[str, Any] | None = None,
        state: str = "done",
    ) -> None:
        """Mark step ``index`` done (or failed); ``data`` is merged into what ``begin_step`` stored."""
        if state not in STEP_STATES[1:]:
            raise ValueError(f"a finished step's state is 'done' or 'failed', not {state!r}")
        key = (steps.c.session_id == session_id) & (steps.c.step_index == index)
        with self._write() as conn:
            old = conn.execute(sa.select(steps.c.data).where(key)).scalar_one_or_none()
            if old is None:
                self._require_session(conn, session_id)
                raise RecordError(f"session {session_id} has no step {index}: begin_step it first")
            merged = {**old, **json_object(data or {}, "data")}
            conn.execute(steps.update().where(key).values(state=state, data=merged, finished_at=self._now()))

    def steps(self, session_id: str) -> list[StepRow]:
        """The session's steps in index order."""
        query = sa.select(steps).where(steps.c.session_id == session_id).order_by(steps.c.step_index)
        with self._read() as conn:
            return [step_row(r) for r in conn.execute(query)]

    def last_completed_step(self, session_id: str) -> int | None:
        """The highest index of a step in state ``done``, or None when none is done."""
        query = sa.select(sa.func.max(steps.c.step_index)).where(
            (steps.c.session_id == session_id) & (steps.c.state == "done")
        )
        with self._read() as conn:
            result: int | None = conn.execute(query).scalar_one()
        return result

    # -- export / import -------------------------------------------------------------------------
    def export_session(self, session_id: str, out_dir: Path) -> Path:
        """Write the session as a self-contained folder ``out_dir/<id>/``; returns that folder."""
        return _export.export_session(self, self.get_session(session_id).id, Path(out_dir))

    def import_session(self, folder: Path) -> SessionRow:
        """Import a folder written by :meth:`export_session`; the session keeps its id.

        The folder is untrusted input (``_import.py``): ImportRefusedError naming the field, and
        nothing written, for anything that is not an unchanged export."""
        with FolderSource(Path(folder)) as source:
            return import_export(self, source)

    def import_archive(self, file: BinaryIO, *, limits: ArchiveLimits | None = None) -> SessionRow:
        """Import a zip of an export (``export.zip``, a zipped folder): :meth:`import_session`'s checks
        and the archive's own caps."""
        with ZipSource(file, limits=limits) as source:
            return import_export(self, source)

    def import_path(self, path: Path) -> SessionRow:
        """Import an export folder, or a zip file of one (``station import``)."""
        with open_source(Path(path)) as source:
            return import_export(self, source)
