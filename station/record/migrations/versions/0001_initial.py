"""The first release's record: sessions, events, steps, captures, measurements.

Revision ID: 0001
Revises:
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

BigId = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
Time = sa.DateTime(timezone=True)


def upgrade() -> None:
    op.create_table(
        "sessions",
        sa.Column("id", sa.String(12), nullable=False),
        sa.Column("kind", sa.String(64), nullable=False),
        sa.Column("state", sa.String(32), nullable=False),
        sa.Column("created_at", Time, nullable=False),
        sa.Column("updated_at", Time, nullable=False),
        sa.Column("params", sa.JSON(), nullable=False),
        sa.Column("config", sa.JSON(), nullable=False),
        sa.Column("identities", sa.JSON(), nullable=False),
        sa.Column("software", sa.JSON(), nullable=False),
        sa.Column("results", sa.JSON(), nullable=True),
        sa.Column("error", sa.Text(), nullable=True),
        sa.Column("parent_id", sa.String(12), nullable=True),
        sa.Column("station", sa.String(128), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_sessions"),
    )
    op.create_index("ix_sessions_kind", "sessions", ["kind"])
    op.create_index("ix_sessions_created_at", "sessions", ["created_at"])
    op.create_index("ix_sessions_parent_id", "sessions", ["parent_id"])

    op.create_table(
        "events",
        sa.Column("id", BigId, autoincrement=True, nullable=False),
        sa.Column("session_id", sa.String(12), nullable=False),
        sa.Column("seq", sa.Integer(), nullable=False),
        sa.Column("time", Time, nullable=False),
        sa.Column("type", sa.String(64), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_events"),
        sa.ForeignKeyConstraint(["session_id"], ["sessions.id"], name="fk_events_session_id_sessions"),
        sa.UniqueConstraint("session_id", "seq", name="uq_events_session_id_seq"),
    )

    op.create_table(
        "steps",
        sa.Column("session_id", sa.String(12), nullable=False),
        sa.Column("step_index", sa.Integer(), autoincrement=False, nullable=False),
        sa.Column("name", sa.String(128), nullable=False),
        sa.Column("state", sa.String(16), nullable=False),
        sa.Column("data", sa.JSON(), nullable=False),
        sa.Column("started_at", Time, nullable=False),
        sa.Column("finished_at", Time, nullable=True),
        sa.PrimaryKeyConstraint("session_id", "step_index", name="pk_steps"),
        sa.ForeignKeyConstraint(["session_id"], ["sessions.id"], name="fk_steps_session_id_sessions"),
    )

    op.create_table(
        "captures",
        sa.Column("id", BigId, autoincrement=True, nullable=False),
        sa.Column("session_id", sa.String(12), nullable=False),
        sa.Column("step_index", sa.Integer(), nullable=False),
        sa.Column("frame_index", sa.Integer(), nullable=False),
        sa.Column("path", sa.String(512), nullable=False),
        sa.Column("width", sa.Integer(), nullable=False),
        sa.Column("height", sa.Integer(), nullable=False),
        sa.Column("dtype", sa.String(16), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("timestamp_s", sa.Double(), nullable=False),
        sa.Column("meta", sa.JSON(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_captures"),
        sa.ForeignKeyConstraint(["session_id"], ["sessions.id"], name="fk_captures_session_id_sessions"),
        sa.UniqueConstraint(
            "session_id", "step_index", "frame_index", name="uq_captures_session_id_step_index_frame_index"
        ),
    )

    op.create_table(
        "measurements",
        sa.Column("id", BigId, autoincrement=True, nullable=False),
        sa.Column("session_id", sa.String(12), nullable=False),
        sa.Column("capture_id", BigId, nullable=False),
        sa.Column("params_hash", sa.String(64), nullable=False),
        sa.Column("software", sa.String(128), nullable=False),
        sa.Column("ok", sa.Boolean(), nullable=False),
        sa.Column("result", sa.JSON(), nullable=False),
        sa.PrimaryKeyConstraint("id", name="pk_measurements"),
        sa.ForeignKeyConstraint(["session_id"], ["sessions.id"], name="fk_measurements_session_id_sessions"),
        sa.ForeignKeyConstraint(["capture_id"], ["captures.id"], name="fk_measurements_capture_id_captures"),
    )
    op.create_index("ix_measurements_session_id", "measurements", ["session_id"])
    op.create_index("ix_measurements_capture_id", "measurements", ["capture_id"])


def downgrade() -> None:
    op.drop_table("measurements")
    op.drop_table("captures")
    op.drop_table("steps")
    op.drop_table("events")
    op.drop_index("ix_sessions_parent_id", "sessions")
    op.drop_index("ix_sessions_created_at", "sessions")
    op.drop_index("ix_sessions_kind", "sessions")
    op.drop_table("sessions")
