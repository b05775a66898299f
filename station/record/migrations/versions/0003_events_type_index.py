"""Events gain an index on (``type``, ``id``): the newest event of one type station-wide
(``Record.last_event``, e.g. the last confirmed table content) is one index seek instead of a read of
every recent session's events.

Nothing is rewritten; the index is built from the rows there.

Revision ID: 0003_events_type_index
Revises: 0002_capture_z
Create Date: 2026-12-02
"""

from __future__ import annotations

from alembic import op

revision = "0003_events_type_index"
down_revision = "0002_capture_z"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_index("ix_events_type_id", "events", ["type", "id"])


def downgrade() -> None:
    op.drop_index("ix_events_type_id", table_name="events")
