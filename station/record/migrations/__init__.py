"""Alembic migrations of the record, run programmatically by ``station.record._engine``."""
