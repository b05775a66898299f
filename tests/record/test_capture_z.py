"""Captures carry the distance sensor's z (migration 0002): stored, exported, imported; a database
made before it still opens, its captures without z."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa
from alembic import command

from station.record import Record
from station.record._engine import _config, upgrade
from tests.record.test_sessions import SNAPSHOT

IMAGE = np.arange(48 * 64, dtype=np.uint16).reshape(48, 64)


def test_z_is_stored_with_the_capture(tmp_path: Path, record_url: str | None) -> None:
    with Record(tmp_path, record_url) as rec:
        s = rec.create_session("repeatability", **SNAPSHOT)
        with_z = rec.save_capture(s.id, 0, 0, IMAGE, timestamp_s=1.0, meta={}, z_mm=68.0123)
        without = rec.save_capture(s.id, 0, 1, IMAGE, timestamp_s=1.0, meta={"z_error": "no target"})
        assert rec.capture(with_z.id).z_mm == pytest.approx(68.0123)
        assert rec.capture(without.id).z_mm is None
        with pytest.raises(ValueError, match="z_mm"):
            rec.save_capture(s.id, 0, 2, IMAGE, timestamp_s=1.0, meta={}, z_mm=float("nan"))
        out = rec.export_session(s.id, tmp_path / "export")
        doc = json.loads((out / "session.json").read_text())
        assert [c["z_mm"] for c in doc["captures"]] == [pytest.approx(68.0123), None]
        assert (out / "captures.csv").read_text().splitlines()[0].endswith(",z_mm")
    with Record(tmp_path / "other", None) as other:
        imported = other.import_session(out)
        assert [c.z_mm for c in other.captures(imported.id)] == [pytest.approx(68.0123), None]


def test_an_export_without_z_imports_with_none(tmp_path: Path) -> None:
    with Record(tmp_path) as rec:
        s = rec.create_session("repeatability", **SNAPSHOT)
        rec.save_capture(s.id, 0, 0, IMAGE, timestamp_s=1.0, meta={})
        out = rec.export_session(s.id, tmp_path / "export")
    doc_path = out / "session.json"
    doc = json.loads(doc_path.read_text())
    for c in doc["captures"]:
        del c["z_mm"]  # as an export made before migration 0002
    doc_path.write_text(json.dumps(doc))
    with Record(tmp_path / "other") as other:
        imported = other.import_session(out)
        assert [c.z_mm for c in other.captures(imported.id)] == [None]


def test_a_database_from_before_the_column_is_upgraded_keeping_its_captures(
    tmp_path: Path, record_url: str | None
) -> None:
    with Record(tmp_path, record_url) as rec:
        s = rec.create_session("repeatability", **SNAPSHOT)
        rec.save_capture(s.id, 0, 0, IMAGE, timestamp_s=1.0, meta={"k": 1}, z_mm=70.0)
        with rec.engine.connect() as conn, conn.begin():
            command.downgrade(_config(conn), "0001")
        with rec.engine.connect() as conn:
            columns = {c["name"] for c in sa.inspect(conn).get_columns("captures")}
            assert "z_mm" not in columns
        upgrade(rec.engine)  # what opening the old database with this software does
        (cap,) = rec.captures(s.id)
        assert (cap.meta, cap.z_mm) == ({"k": 1}, None)
