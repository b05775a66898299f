"""The record's tables (SQLAlchemy Core), as the Alembic migrations leave them.

A test compares this metadata with the migrations' head (``alembic check``'s comparison), so a change
here needs a new revision in ``migrations/versions/``.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Dialect

NAMING = {
    "ix": "ix_%(table_name)s_%(column_0_N_name)s",
    "uq": "uq_%(table_name)s_%(column_0_N_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}

metadata = sa.MetaData(naming_convention=NAMING)

# 64-bit ids on servers; SQLite's INTEGER PRIMARY KEY (the rowid) is already 64-bit and only that
# spelling autoincrements there.
BigId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")


class UTCDateTime(sa.TypeDecorator[datetime]):
    """Timezone-aware UTC datetimes on every backend (SQLite stores them naive, in UTC)."""

    impl = sa.DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError(f"naive datetime {value!r}: the record stores aware (UTC) times only")
        value = value.astimezone(UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: Any, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        assert isinstance(value, datetime)
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


def new_id(result: sa.CursorResult[Any]) -> int:
    """The id the database gave the row just inserted."""
    key = result.inserted_primary_key
    if key is None or key[0] is None:
        raise RuntimeError("the database returned no id for the inserted row")
    return int(key[0])


sessions = sa.Table(
    "sessions",
    metadata,
    sa.Column("id", sa.String(12), primary_key=True),
    sa.Column("kind", sa.String(64), nullable=False, index=True),
    sa.Column("state", sa.String(32), nullable=False),
    sa.Column("created_at", UTCDateTime(), nullable=False, index=True),
    sa.Column("updated_at", UTCDateTime(), nullable=False),
    sa.Column("params", sa.JSON(), nullable=False),
    sa.Column("config", sa.JSON(), nullable=False),
    sa.Column("identities", sa.JSON(), nullable=False),
    sa.Column("software", sa.JSON(), nullable=False),
    sa.Column("results", sa.JSON(), nullable=True),
    sa.Column("error", sa.Text(), nullable=True),
    # Not a foreign key: a parent may live in another station's record (export/import).
    sa.Column("parent_id", sa.String(12), nullable=True, index=True),
    sa.Column("station", sa.String(128), nullable=False),
)

events = sa.Table(
    "events",
    metadata,
    sa.Column("id", BigId, primary_key=True, autoincrement=True),
    sa.Column("session_id", sa.String(12), sa.ForeignKey("sessions.id"), nullable=False),
    sa.Column("seq", sa.Integer(), nullable=False),
    sa.Column("time", UTCDateTime(), nullable=False),
    sa.Column("type", sa.String(64), nullable=False),
    sa.Column("data", sa.JSON(), nullable=False),
    sa.UniqueConstraint("session_id", "seq"),
    # the newest event of one type, station-wide (``Record.last_event``; migration 0003)
    sa.Index("ix_events_type_id", "type", "id"),
)

steps = sa.Table(
    "steps",
    metadata,
    sa.Column("session_id", sa.String(12), sa.ForeignKey("sessions.id"), primary_key=True),
    sa.Column("step_index", sa.Integer(), primary_key=True, autoincrement=False),
    sa.Column("name", sa.String(128), nullable=False),
    sa.Column("state", sa.String(16), nullable=False),
    sa.Column("data", sa.JSON(), nullable=False),
    sa.Column("started_at", UTCDateTime(), nullable=False),
    sa.Column("finished_at", UTCDateTime(), nullable=True),
)

captures = sa.Table(
    "captures",
    metadata,
    sa.Column("id", BigId, primary_key=True, autoincrement=True),
    sa.Column("session_id", sa.String(12), sa.ForeignKey("sessions.id"), nullable=False),
    sa.Column("step_index", sa.Integer(), nullable=False),
    sa.Column("frame_index", sa.Integer(), nullable=False),
    sa.Column("path", sa.String(512), nullable=False),
    sa.Column("width", sa.Integer(), nullable=False),
    sa.Column("height", sa.Integer(), nullable=False),
    sa.Column("dtype", sa.String(16), nullable=False),
    sa.Column("sha256", sa.String(64), nullable=False),
    sa.Column("timestamp_s", sa.Double(), nullable=False),
    sa.Column("meta", sa.JSON(), nullable=False),
    sa.UniqueConstraint("session_id", "step_index", "frame_index"),
    # the distance sensor's reading with the frame, mm (migration 0002); NULL without one
    sa.Column("z_mm", sa.Double(), nullable=True),
)

measurements = sa.Table(
    "measurements",
    metadata,
    sa.Column("id", BigId, primary_key=True, autoincrement=True),
    sa.Column("session_id", sa.String(12), sa.ForeignKey("sessions.id"), nullable=False, index=True),
    sa.Column("capture_id", BigId, sa.ForeignKey("captures.id"), nullable=False, index=True),
    sa.Column("params_hash", sa.String(64), nullable=False),
    sa.Column("software", sa.String(128), nullable=False),
    sa.Column("ok", sa.Boolean(), nullable=False),
    sa.Column("result", sa.JSON(), nullable=False),
)
