"""Alembic environment: always run with a connection handed in by ``station.record._engine``.

There is no alembic.ini: ``upgrade(connection)`` builds the configuration in code, so migrations run
from an installed package. The caller holds the transaction (and the lock that serialises migrations).
"""

from __future__ import annotations

from alembic import context

from station.record._schema import metadata

connection = context.config.attributes.get("connection")
if connection is None:
    raise RuntimeError("run the record's migrations through station.record (Record opens them)")

context.configure(
    connection=connection,
    target_metadata=metadata,
    render_as_batch=True,  # SQLite alters tables by copying them
    compare_type=True,
)
with context.begin_transaction():
    context.run_migrations()
