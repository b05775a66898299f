"""Opening the record's database: the engine, SQLite's settings, and the migrations to head.

SQLite (the default) runs in WAL mode so that readers (the web API, ``station sessions``) never wait
on the runner's writes; writes begin ``IMMEDIATE`` so two writers queue on the busy timeout instead of
failing half-way; foreign keys are enforced; commits are synchronous (``FULL``) because a capture's row
must not outlive a power cut that its image survived, nor the reverse. Any other SQLAlchemy URL is used
as given (PostgreSQL: ``postgresql+psycopg://user:password@host/db``).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from sqlalchemy import event

from station.record._errors import RecordError

MIGRATIONS = Path(__file__).with_name("migrations")
SQLITE_FILE = "record.sqlite"
BEGIN_OPTION = "station_begin"
# Any constant works: it only has to be the same for every process migrating the same server.
_PG_MIGRATION_LOCK = 0x5_7A71_0E


def redact(url: str | sa.URL) -> str:
    """The URL with its password hidden, fit for messages and logs."""
    return sa.make_url(url).render_as_string(hide_password=True)


def _sqlite_settings(engine: sa.Engine, busy_timeout_s: float) -> None:
    @event.listens_for(engine, "connect")
    def _connect(dbapi_connection: Any, _record: Any) -> None:
        dbapi_connection.isolation_level = None  # SQLAlchemy emits BEGIN itself (below)
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA journal_mode=WAL")
        cursor.execute(f"PRAGMA busy_timeout={int(busy_timeout_s * 1000)}")
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA synchronous=NORMAL")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _begin(conn: sa.Connection) -> None:
        mode = conn.get_execution_options().get(BEGIN_OPTION, "DEFERRED")
        conn.exec_driver_sql(f"BEGIN {mode}")


def create_engine(data_dir: Path, url: str | None, *, busy_timeout_s: float) -> sa.Engine:
    """An engine on ``url``, or on ``data_dir/record.sqlite`` when ``url`` is None."""
    if url is None:
        url = f"sqlite:///{(data_dir / SQLITE_FILE).resolve()}"
    try:
        parsed = sa.make_url(url)
        engine = sa.create_engine(parsed, pool_pre_ping=parsed.get_backend_name() != "sqlite")
    except sa.exc.ArgumentError as exc:
        raise RecordError(
            f"not a database URL: {url!r} ({exc}); give a SQLAlchemy URL such as "
            "postgresql+psycopg://user@host/station, or none for SQLite in the data directory"
        ) from exc
    except ModuleNotFoundError as exc:
        raise RecordError(f"no database driver for {redact(url)}: {exc.name} is not installed") from exc
    if engine.dialect.name == "sqlite":
        _sqlite_settings(engine, busy_timeout_s)
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
        raise RecordError(f"cannot open the record at {redact(engine.url)}: {exc.orig}") from exc


@functools.cache
def head_revision() -> str:
    """The newest migration's revision id."""
    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    head = ScriptDirectory.from_config(config).get_current_head()
    if head is None:
        raise RecordError(f"no migrations found in {MIGRATIONS}: the installation is incomplete")
    return head
