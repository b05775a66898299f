"""A record opened read-only (``station sessions``, ``report``, ``export``) reads everything and writes
nothing: no file is created, no migration runs, every write is refused (SQLite and PostgreSQL)."""

from __future__ import annotations

from pathlib import Path

import pytest

from station.record import NoRecordError, Record, RecordError
from tests.record.conftest import NewUrl, StepClock
from tests.record.importing import rows, tree
from tests.record.test_export import _fill


def test_a_read_only_record_reads_and_refuses_every_write(tmp_path: Path, new_url: NewUrl) -> None:
    url = new_url()
    with Record(tmp_path / "data", url, clock=StepClock()) as writer:
        sid = _fill(writer)
        before = tree(writer.data_dir), rows(writer)
    with Record(tmp_path / "data", url, read_only=True) as reader:
        assert reader.read_only
        assert [s.id for s in reader.list_sessions()] == [sid]
        assert len(reader.captures(sid)) == 6
        reader.load_image(reader.captures(sid)[0])
        reader.export_session(sid, tmp_path / "out")
        with pytest.raises(RecordError, match="opened read-only"):
            reader.set_state(sid, "failed")
        with pytest.raises(RecordError, match="opened read-only"):
            reader.import_session(tmp_path / "out" / sid)
        assert (tree(reader.data_dir), rows(reader)) == before


def test_no_record_is_said_so_and_nothing_is_created(tmp_path: Path) -> None:
    with pytest.raises(NoRecordError, match="nothing has been recorded there yet"):
        Record(tmp_path / "none", read_only=True)
    assert not (tmp_path / "none").exists()
    (tmp_path / "empty").mkdir()
    with pytest.raises(NoRecordError):
        Record(tmp_path / "empty", read_only=True)
    assert list((tmp_path / "empty").iterdir()) == []
