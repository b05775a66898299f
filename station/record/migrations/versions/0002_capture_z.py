"""Captures gain ``z_mm``: the distance sensor's reading with the frame (NULL without a sensor).

Nullable, so every older capture stays valid as it is; nothing is rewritten.

Revision ID: 0002_capture_z
Revises: 0001
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002_capture_z"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("captures", sa.Column("z_mm", sa.Double(), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("captures") as batch:
        batch.drop_column("z_mm")
