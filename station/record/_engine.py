"""Opening the record's database: the engine, SQLite's settings, and the migrations to head.

SQLite (the default) runs in WAL mode so that readers (the web API, ``station sessions``) never wait
on the runner's writes; writes begin ``IMMEDIATE`` so two writers queue on the busy timeout instead of
failing half-way; foreign keys are enforced; commits are synchronous (``FULL``) because a capture's row
must not outlive a power cut that its image survived, nor the reverse. Any other SQLAlchemy URL is used
as given (PostgreSQL: ``postgresql+psycopg://user:password@host/db``).

A record opened **read-only** (``station sessions``, ``report``, ``export``) is never migrated and
never written: SQLite is opened with ``mode=ro`` and ``query_only`` when another connection's WAL index
(``record.sqlite-shm``) is there, as a normal connection that only reads when the directory has room
for SQLite's transient files (which it removes again), and otherwise (a full disk, a read-only
directory, where no writer can run either) as an immutable file; PostgreSQL sessions are read-only
transactions. Passwords of the URL (user part and query) never appear in its messages.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any
from urllib.parse import quote

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import event

from station.record._errors import NoRecordError, RecordError
from station.redaction import redact_url, scrub, url_secrets

MIGRATIONS = Path(__file__).with_name("migrations")
SQLITE_FILE = "record.sqlite"
BEGIN_OPTION = "station_begin"
# Any constant works: it only has to be the same for every process migrating the same server.
_PG_MIGRATION_LOCK = 0x5_7A71_0E


#: Free space a read-only SQLite reader needs to open the record normally (SQLite's WAL index is 32 kB).
_READER_ROOM_BYTES = 1 << 20


def redact(url: str | sa.URL) -> str:
    """The URL with its passwords hidden (user part and secret query parameters), for messages and logs."""
    text = url.render_as_string(hide_password=False) if isinstance(url, sa.URL) else str(url)
    return redact_url(text)


def secrets_of(url: str | sa.URL) -> list[str]:
    """The URL's secret values, to scrub them from a driver's messages (``station.redaction.scrub``)."""
    text = url.render_as_string(hide_password=False) if isinstance(url, sa.URL) else str(url)
    found = url_secrets(text)
    if isinstance(url, sa.URL) and url.password:
        found.append(str(url.password))
    return found


def reason(exc: BaseException, url: str | sa.URL) -> str:
    """A database error's own text (``exc.orig`` for a DBAPI error) without the URL's secrets."""
    orig = getattr(exc, "orig", None)
    return scrub(str(orig if orig is not None else exc), secrets_of(url))


def _sqlite_settings(engine: sa.Engine, busy_timeout_s: float, *, read_only: bool) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN itself (below)
        cursor = dbapi_connection.cursor()
        if read_only:
            cursor.execute("PRAGMA query_only=ON")
        else:
            cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute(f"PRAGMA busy_timeout={int(busy_timeout_s * 1000)}")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: sa.Connection) -> None:
        mode = conn.get_execution_options().get(BEGIN_OPTION, "DEFERRED")
        conn.exec_driver_sql(f"BEGIN {mode}")


def _read_only_server(engine: sa.Engine) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, _record: Any) -> None:
        cursor = dbapi_connection.cursor()
        cursor.execute("SET SESSION CHARACTERISTICS AS TRANSACTION READ ONLY")
        cursor.close()
        dbapi_connection.commit()


def _room_for_reader(directory: Path) -> bool:
    """Whether SQLite may create its transient files in ``directory`` (writable, not full)."""
    if not os.access(directory, os.W_OK | os.X_OK):
        return False
    try:
        st = os.statvfs(directory)
    except OSError:
        return False
    return st.f_bavail * st.f_frsize >= _READER_ROOM_BYTES and st.f_favail > 16


def sqlite_url(path: Path, *, read_only: bool = False) -> sa.URL:
    """The URL of the SQLite record at ``path`` (see the module notes for the read-only modes)."""
    if not read_only:
        return sa.URL.create("sqlite", database=str(path))
    if not path.is_file():
        raise NoRecordError(path.parent)
    if Path(f"{path}-shm").exists():
        mode = {"mode": "ro"}
    elif _room_for_reader(path.parent):
        mode = {"mode": "rw"}
    else:
        mode = {"mode": "ro", "immutable": "1"}
    return sa.URL.create("sqlite", database="file:" + quote(str(path)), query={**mode, "uri": "true"})


def create_engine(
    data_dir: Path, url: str | None, *, busy_timeout_s: float, read_only: bool = False
) -> sa.Engine:
    """An engine on ``url``, or on ``data_dir/record.sqlite`` when ``url`` is None."""
    try:
        if url is None:
            parsed = sqlite_url((data_dir / SQLITE_FILE).resolve(), read_only=read_only)
        else:
            parsed = sa.make_url(url)
        engine = sa.create_engine(parsed, pool_pre_ping=parsed.get_backend_name() != "sqlite")
    except sa.exc.ArgumentError as exc:
        raise RecordError(
            f"not a database URL: {redact(str(url))!r} ({reason(exc, str(url))}); give a SQLAlchemy URL "
            "such as postgresql+psycopg://user@host/station, or none for SQLite in the data directory"
        ) from exc
    except ModuleNotFoundError as exc:
        raise RecordError(f"no database driver for {redact(str(url))}: {exc.name} is not installed") from exc
    if engine.dialect.name == "sqlite":
        _sqlite_settings(engine, busy_timeout_s, read_only=read_only)
    elif read_only and engine.dialect.name == "postgresql":
        _read_only_server(engine)
    return engine


def _config(connection: sa.Connection) -> Config:
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["connection"] = connection
    return config


def upgrade(engine: sa.Engine) -> None:
    """Bring the database to the migrations' head, one process at a time.

    A record already at head is only read (no write lock), so opening one never waits on a writer.
    """
    try:
        with engine.connect() as conn:
            current = MigrationContext.configure(conn).get_current_revision()
        if current == head_revision():
            return
        with engine.connect() as conn:
            conn = conn.execution_options(**{BEGIN_OPTION: "IMMEDIATE"})
            with conn.begin():
                if conn.dialect.name == "postgresql":
                    conn.execute(sa.text("SELECT pg_advisory_xact_lock(:key)"), {"key": _PG_MIGRATION_LOCK})
                command.upgrade(_config(conn), "head")
    except sa.exc.OperationalError as exc:
        hint = (
            " (its directory must be writable and have free space)" if engine.dialect.name == "sqlite" else ""
        )
        raise RecordError(
            f"cannot open the record at {redact(engine.url)}: {reason(exc, engine.url)}{hint}"
        ) from exc


def check_head(engine: sa.Engine, data_dir: Path) -> None:
    """A read-only opening: the record must be at the migrations' head already (nothing is migrated)."""
    try:
        with engine.connect() as conn:
            current = MigrationContext.configure(conn).get_current_revision()
    except sa.exc.DBAPIError as exc:
        raise RecordError(
            f"cannot read the record at {redact(engine.url)}: {reason(exc, engine.url)}"
        ) from exc
    if current is None:
        raise NoRecordError(data_dir)
    if current != head_revision():
        raise RecordError(
            f"the record at {redact(engine.url)} has schema revision {current}, not this software's "
            f"{head_revision()}: a command that writes (station run, station import, station serve) "
            "migrates it, or use the station software that wrote it"
        )


def open_engine(
    data_dir: Path, url: str | None, *, busy_timeout_s: float, read_only: bool
) -> tuple[sa.Engine, str]:
    """The record's engine (migrated to head, or checked to be there when read-only) and its URL as
    shown (passwords hidden). Writing, the data directory is created if missing; read-only, a missing
    one is a NoRecordError."""
    if read_only:
        if not data_dir.is_dir():
            raise NoRecordError(data_dir)
    else:
        try:
            data_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RecordError(f"cannot create the data directory {data_dir}: {exc.strerror}") from exc
    shown = redact(url if url is not None else f"sqlite:///{(data_dir / SQLITE_FILE).resolve()}")
    engine = create_engine(data_dir, url, busy_timeout_s=busy_timeout_s, read_only=read_only)
    try:
        if read_only:
            check_head(engine, data_dir)
        else:
            upgrade(engine)
    except BaseException:
        engine.dispose()
        raise
    return engine, shown


@functools.cache
def head_revision() -> str:
    """The newest migration's revision id."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    head = ScriptDirectory.from_config(config).get_current_head()
    if head is None:
        raise RecordError(f"no migrations found in {MIGRATIONS}: the installation is incomplete")
    return head
