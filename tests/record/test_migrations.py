"""The schema comes from Alembic migrations shipped in the package, and matches the models."""

from __future__ import annotations

from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext

import station
from station.record import Record
from station.record._engine import MIGRATIONS, _config, head_revision, upgrade
from station.record._schema import metadata
from tests.record.test_sessions import SNAPSHOT

TABLES = {"sessions", "events", "steps", "captures", "measurements", "alembic_version"}


def test_empty_database_is_migrated_to_head_on_open(tmp_path: Path, record_url: str | None) -> None:
    with Record(tmp_path, record_url) as rec, rec.engine.connect() as conn:
        assert set(sa.inspect(conn).get_table_names()) == TABLES
        assert MigrationContext.configure(conn).get_current_revision() == head_revision()


def test_models_match_the_migrations_head(tmp_path: Path, record_url: str | None) -> None:
    """``alembic check``: autogenerate finds nothing to add, drop or alter."""
    with Record(tmp_path, record_url) as rec, rec.engine.connect() as conn:
        context = MigrationContext.configure(conn, opts={"compare_type": True})
        assert compare_metadata(context, metadata) == []


def test_downgrade_to_base_and_up_again(tmp_path: Path, record_url: str | None) -> None:
    with Record(tmp_path, record_url) as rec:
        rec.create_session("validation", **SNAPSHOT)
        with rec.engine.connect() as conn, conn.begin():
            command.downgrade(_config(conn), "base")
        with rec.engine.connect() as conn:
            assert set(sa.inspect(conn).get_table_names()) == {"alembic_version"}
        upgrade(rec.engine)
        assert rec.list_sessions() == []
        rec.create_session("validation", **SNAPSHOT)
        assert len(rec.list_sessions()) == 1


def test_reopening_keeps_the_data(tmp_path: Path, record_url: str | None) -> None:
    with Record(tmp_path, record_url) as rec:
        made = rec.create_session("validation", **SNAPSHOT)
    with Record(tmp_path, record_url) as rec:
        assert rec.get_session(made.id) == made


def test_migrations_ship_inside_the_package() -> None:
    assert station.__file__ is not None  # a regular package, not a namespace one
    assert MIGRATIONS.is_relative_to(Path(station.__file__).parent)
    assert (MIGRATIONS / "env.py").is_file()
    assert sorted(p.name for p in (MIGRATIONS / "versions").glob("0*.py")) == [
        "0001_initial.py",
        "0002_capture_z.py",
        "0003_events_type_index.py",
    ]
    pyproject = (Path(__file__).parents[2] / "pyproject.toml").read_text()
    assert (
        '"station.record" = ["migrations/*.py", "migrations/*.mako", "migrations/versions/*.py"]' in pyproject
    )
