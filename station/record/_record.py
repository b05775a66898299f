"""The record: sessions, their steps, events, captures and measurements, in one database.

Images live as PNG files under ``DATA_DIR/images/<session>/``; the database holds their paths and
sha256. Every method is one short transaction, so the runner, the web API and ``station sessions``
can share one record from several threads and processes; nothing image-sized is kept in memory.
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import re
import uuid
from collections.abc import Callable, Iterator, Mapping
from datetime import UTC, datetime
from pathlib import Path
from types import TracebackType
from typing import Any, Self

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa

from station.record import _export, _images
from station.record._engine import BEGIN_OPTION, create_engine, redact, upgrade
from station.record._errors import RecordError, RecordNotFoundError, error_of
from station.record._json import json_object, params_hash, strip_point_arrays
from station.record._rows import STEP_STATES, CaptureRow, EventRow, MeasurementRow, SessionRow, StepRow
from station.record._schema import captures, events, measurements, new_id, sessions, steps

Clock = Callable[[], datetime]
_HEX_PREFIX = re.compile(r"[0-9a-f]{4,12}")
_SESSION_ID = re.compile(r"[0-9a-f]{12}")
MIN_PREFIX = 4


def _utc_now() -> datetime:
    return datetime.now(UTC)


def random_session_id() -> str:
    """12 lowercase hex digits from a random UUID (about 2.8e14 values)."""
    return uuid.uuid4().hex[:12]


def session_row(r: sa.Row[Any]) -> SessionRow:
    return SessionRow(
        id=r.id,
        kind=r.kind,
        state=r.state,
        created_at=r.created_at,
        updated_at=r.updated_at,
        params=r.params,
        config=r.config,
        identities=r.identities,
        software=r.software,
        results=r.results,
        error=r.error,
        parent_id=r.parent_id,
        station=r.station,
    )


def event_row(r: sa.Row[Any]) -> EventRow:
    return EventRow(id=r.id, session_id=r.session_id, seq=r.seq, time=r.time, type=r.type, data=r.data)


def step_row(r: sa.Row[Any]) -> StepRow:
    return StepRow(
        session_id=r.session_id,
        index=r.step_index,
        name=r.name,
        state=r.state,
        data=r.data,
        started_at=r.started_at,
        finished_at=r.finished_at,
    )


def capture_row(r: sa.Row[Any]) -> CaptureRow:
    return CaptureRow(
        id=r.id,
        session_id=r.session_id,
        step_index=r.step_index,
        frame_index=r.frame_index,
        path=r.path,
        width=r.width,
        height=r.height,
        dtype=r.dtype,
        sha256=r.sha256,
        timestamp_s=r.timestamp_s,
        meta=r.meta,
        z_mm=r.z_mm,
    )


def measurement_row(r: sa.Row[Any]) -> MeasurementRow:
    return MeasurementRow(
        id=r.id,
        session_id=r.session_id,
        capture_id=r.capture_id,
        params_hash=r.params_hash,
        software=r.software,
        ok=r.ok,
        result=r.result,
    )


def capture_path(session_id: str, step_index: int, frame_index: int) -> str:
    """A capture's image path relative to the data directory."""
    return f"images/{session_id}/{step_index:05d}-{frame_index:02d}.png"


class Record:
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
    """

    def __init__(
        self,
        data_dir: Path,
        url: str | None = None,
        *,
        clock: Clock = _utc_now,
        make_id: Callable[[], str] = random_session_id,
        busy_timeout_s: float = 30.0,
    ) -> None:
        self._data_dir = Path(data_dir)
        try:
            self._data_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordError(f"cannot create the data directory {self._data_dir}: {exc.strerror}") from exc
        self._clock = clock
        self._make_id = make_id
        self._engine = create_engine(self._data_dir, url, busy_timeout_s=busy_timeout_s)
        try:
            upgrade(self._engine)
        except BaseException:
            self._engine.dispose()
            raise

    # -- lifecycle -------------------------------------------------------------------------------
    @property
    def data_dir(self) -> Path:
        return self._data_dir

    @property
    def url(self) -> str:
        """The database URL with any password hidden."""
        return redact(self._engine.url)

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
        try:
            with self._engine.connect() as conn:
                conn = conn.execution_options(**{BEGIN_OPTION: "IMMEDIATE"})
                with conn.begin():
                    yield conn
        except sa.exc.DBAPIError as exc:
            raise error_of(exc)(
                f"cannot write to the record at {self.url}: {exc.orig}; nothing of this change was "
                "recorded (check free space and the database server)"
            ) from exc

    @contextlib.contextmanager
    def _read(self) -> Iterator[sa.Connection]:
        try:
            with self._engine.connect() as conn:
                yield conn
        except sa.exc.DBAPIError as exc:
            raise error_of(exc)(f"cannot read the record at {self.url}: {exc.orig}") from exc

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
        if not _SESSION_ID.fullmatch(session_id):
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
            names = ", ".join(r.id for r in rows)
            raise RecordError(
                f"session prefix {id_or_prefix!r} is ambiguous: it matches {names}; give more characters"
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
        with self._write() as conn:
            done = conn.execute(
                sessions.update()
                .where(sessions.c.id == session_id)
                .values(state=state, error=error, updated_at=self._now())
            )
            if done.rowcount == 0:
                raise RecordNotFoundError(session_id, self.url)

    def set_results(self, session_id: str, results: Mapping[str, Any]) -> None:
        """Store the session's results (replacing any earlier ones)."""
        value = json_object(results, "results")
        with self._write() as conn:
            done = conn.execute(
                sessions.update()
                .where(sessions.c.id == session_id)
                .values(results=value, updated_at=self._now())
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

    # -- captures --------------------------------------------------------------------------------
    def save_capture(
        self,
        session_id: str,
        step_index: int,
        frame_index: int,
        image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16],
        *,
        timestamp_s: float,
        meta: Mapping[str, Any],
        z_mm: float | None = None,
    ) -> CaptureRow:
        """Store a frame as a lossless PNG (atomically, durably), then its row.

        ``z_mm``: the distance sensor's reading with the frame (mm), if any.

        Raises
        ------
        RecordWriteError
            The file could not be written (disk full ...): no file, no row.
        """
        image = _images.check_image(image)
        if step_index < 0 or frame_index < 0:
            raise ValueError(f"step and frame indices must be >= 0, not {step_index}, {frame_index}")
        if z_mm is not None and not math.isfinite(z_mm):
            raise ValueError(f"z_mm must be a finite distance in mm or None, not {z_mm!r}")
        meta_value = json_object(meta, "meta")
        rel = capture_path(session_id, step_index, frame_index)
        with self._read() as conn:
            self._require_session(conn, session_id)
            taken = conn.execute(
                sa.select(captures.c.id).where(
                    (captures.c.session_id == session_id)
                    & (captures.c.step_index == step_index)
                    & (captures.c.frame_index == frame_index)
                )
            ).first()
        if taken is not None:
            raise RecordError(
                f"session {session_id} already has step {step_index} frame {frame_index} (capture "
                f"{taken.id}); frames are never overwritten: re-begin the step to capture it again"
            )
        data = _images.encode_png(image)
        sha = hashlib.sha256(data).hexdigest()
        path = self._data_dir / rel
        _images.write_atomic(path, data)
        del data
        values: dict[str, Any] = {
            "session_id": session_id,
            "step_index": step_index,
            "frame_index": frame_index,
            "path": rel,
            "width": int(image.shape[1]),
            "height": int(image.shape[0]),
            "dtype": image.dtype.name,
            "sha256": sha,
            "timestamp_s": float(timestamp_s),
            "meta": meta_value,
            "z_mm": None if z_mm is None else float(z_mm),
        }
        try:
            with self._write() as conn:
                capture_id = new_id(conn.execute(captures.insert().values(**values)))
        except RecordError:
            path.unlink(missing_ok=True)  # no row names it: an orphan would only mislead
            raise
        return CaptureRow(id=capture_id, **values)

    def captures(self, session_id: str, *, step_index: int | None = None) -> list[CaptureRow]:
        """The session's captures (of one step, if given), by step then frame."""
        query = sa.select(captures).where(captures.c.session_id == session_id)
        if step_index is not None:
            query = query.where(captures.c.step_index == step_index)
        query = query.order_by(captures.c.step_index, captures.c.frame_index)
        with self._read() as conn:
            return [capture_row(r) for r in conn.execute(query)]

    def capture(self, capture_id: int) -> CaptureRow:
        """One capture by id."""
        with self._read() as conn:
            r = conn.execute(sa.select(captures).where(captures.c.id == capture_id)).first()
        if r is None:
            raise RecordError(f"no capture {capture_id} in the record at {self.url}")
        return capture_row(r)

    def load_image(self, capture: CaptureRow) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16]:
        """The capture's image, after checking the file's sha256 against the record."""
        return _images.read_checked(self._data_dir / capture.path, capture.sha256)

    # -- measurements ----------------------------------------------------------------------------
    def add_measurement(
        self,
        session_id: str,
        capture_id: int,
        result: Mapping[str, Any],
        *,
        params: Mapping[str, Any],
        software: str,
    ) -> MeasurementRow:
        """Store one measurement (the ``station measure --json`` object, point arrays stripped)."""
        value: dict[str, Any] = strip_point_arrays(json_object(result, "result"))
        phash = params_hash(params)
        with self._write() as conn:
            self._require_session(conn, session_id)
            if conn.execute(sa.select(captures.c.id).where(captures.c.id == capture_id)).first() is None:
                raise RecordError(f"no capture {capture_id} in the record at {self.url} to measure")
            values: dict[str, Any] = {
                "session_id": session_id,
                "capture_id": capture_id,
                "params_hash": phash,
                "software": software,
                "ok": bool(value.get("ok", False)),
                "result": value,
            }
            mid = new_id(conn.execute(measurements.insert().values(**values)))
        return MeasurementRow(id=mid, **values)

    def measurements(self, session_id: str) -> list[MeasurementRow]:
        """The session's measurements in the order they were stored."""
        query = sa.select(measurements).where(measurements.c.session_id == session_id)
        with self._read() as conn:
            return [measurement_row(r) for r in conn.execute(query.order_by(measurements.c.id))]

    # -- export / import -------------------------------------------------------------------------
    def export_session(self, session_id: str, out_dir: Path) -> Path:
        """Write the session as a self-contained folder ``out_dir/<id>/``; returns that folder."""
        return _export.export_session(self, self.get_session(session_id).id, Path(out_dir))

    def import_session(self, folder: Path) -> SessionRow:
        """Import a folder written by :meth:`export_session`; the session keeps its id."""
        return _export.import_session(self, Path(folder))
