"""Sessions: creation, lookup by id or prefix, listing, states and results (SQLite and PostgreSQL)."""

from __future__ import annotations

import itertools
from pathlib import Path
from typing import Any, TypedDict

import numpy as np
import pytest

from station.record import Record, RecordError, RecordNotFoundError
from tests.record.conftest import StepClock


class Snapshot(TypedDict):
    """What ``Record.create_session`` takes besides the kind, as keyword arguments (``**SNAPSHOT``)."""

    params: dict[str, Any]
    config: dict[str, Any]
    identities: dict[str, Any]
    software: dict[str, Any]


SNAPSHOT: Snapshot = {
    "params": {"cycles": 30, "joints": [1, 2, 3]},
    "config": {"camera": {"kind": "sim"}, "reference_pose": [0.0, -30.0, 90.0, 0.0, 30.0, 0.0]},
    "identities": {"robot": {"model": "A465", "firmware": "C500C 2.1"}},
    "software": {"station": "0.1.0", "numpy": "2"},
}


def test_creates_idle_session_with_hex_id_and_reads_it_back(record: Record) -> None:
    row = record.create_session("repeatability", **SNAPSHOT, station="bench-1")
    assert len(row.id) == 12
    assert int(row.id, 16) >= 0
    assert row.id == row.id.lower()
    assert row.state == "idle"
    assert row.results is None
    assert row.error is None
    assert row.station == "bench-1"
    assert row.created_at.tzinfo is not None
    assert record.get_session(row.id) == row


def test_finds_session_by_unique_prefix_of_four_or_more(record: Record) -> None:
    row = record.create_session("validation", **SNAPSHOT)
    assert record.get_session(row.id[:4]) == row
    assert record.get_session(row.id[:7].upper()) == row
    with pytest.raises(RecordError, match="too short"):
        record.get_session(row.id[:3])


def test_ambiguous_prefix_names_the_matches(tmp_path: Path, record_url: str | None) -> None:
    ids = iter(["abcd00000001", "abcd00000002", "ffff00000003"])
    with Record(tmp_path / "d", record_url, make_id=lambda: next(ids)) as rec:
        for _ in range(3):
            rec.create_session("validation", **SNAPSHOT)
        with pytest.raises(RecordError, match="abcd00000001, abcd00000002") as err:
            rec.get_session("abcd")
        assert not isinstance(err.value, RecordNotFoundError)
        assert rec.get_session("abcd00000002").id == "abcd00000002"
        assert rec.get_session("ffff").id == "ffff00000003"


def test_unknown_session_says_how_to_list_them(record: Record) -> None:
    with pytest.raises(RecordNotFoundError, match=r"no session 'ab12' in the record at .*station sessions"):
        record.get_session("ab12")
    with pytest.raises(RecordNotFoundError):
        record.get_session("not-hex!")
    with pytest.raises(RecordNotFoundError):
        record.set_state("ab12ab12ab12", "running")


def test_lists_newest_first_and_by_kind(record: Record) -> None:
    made = [record.create_session(kind, **SNAPSHOT) for kind in ("validation", "repeatability", "validation")]
    assert [s.id for s in record.list_sessions()] == [s.id for s in reversed(made)]
    assert [s.id for s in record.list_sessions("validation")] == [made[2].id, made[0].id]
    assert record.list_sessions("sweep") == []


def test_state_error_and_results_are_stored(record: Record) -> None:
    row = record.create_session("validation", **SNAPSHOT)
    record.set_state(row.id, "running")
    record.set_state(row.id, "failed", error="camera timeout after 5 s")
    failed = record.get_session(row.id)
    assert failed.state == "failed"
    assert failed.error == "camera timeout after 5 s"
    assert failed.updated_at > row.updated_at
    results = {"mean_um": np.float64(0.05), "rp_mm": {"J1": 0.0166}, "bad": float("nan")}
    record.set_results(row.id, results)
    record.set_state(row.id, "succeeded")
    done = record.get_session(row.id)
    assert done.results == {"mean_um": 0.05, "rp_mm": {"J1": 0.0166}, "bad": None}
    assert type(done.results["mean_um"]) is float
    assert done.error is None


def test_parent_must_exist(record: Record) -> None:
    parent = record.create_session("validation", **SNAPSHOT)
    child = record.create_session("reanalyse", **SNAPSHOT, parent_id=parent.id)
    assert record.get_session(child.id).parent_id == parent.id
    with pytest.raises(RecordNotFoundError):
        record.create_session("reanalyse", **SNAPSHOT, parent_id="0123456789ab")


def test_rejects_what_json_cannot_hold(record: Record) -> None:
    with pytest.raises(TypeError, match="params must be a dict"):
        record.create_session("validation", **{**SNAPSHOT, "params": [1, 2]})  # type: ignore[arg-type]
    unstorable: Snapshot = {**SNAPSHOT, "config": {"x": object()}}
    with pytest.raises(TypeError, match="cannot store a object"):
        record.create_session("validation", **unstorable)


def test_url_hides_the_password(tmp_path: Path) -> None:
    with Record(tmp_path) as rec:
        assert rec.url == f"sqlite:///{(tmp_path / 'record.sqlite').resolve()}"
    with pytest.raises(RecordError, match="cannot open the record at postgresql\\+psycopg://u:\\*\\*\\*@"):
        Record(tmp_path, "postgresql+psycopg://u:secret@/nodb?host=/nonexistent&connect_timeout=2")


def test_bad_url_is_a_record_error(tmp_path: Path) -> None:
    with pytest.raises(RecordError, match="not a database URL"):
        Record(tmp_path, "no url at all")


def test_clock_must_be_aware(tmp_path: Path) -> None:
    clock = StepClock()
    naive = (clock().replace(tzinfo=None) for _ in itertools.count())
    with Record(tmp_path, clock=lambda: next(naive)) as rec, pytest.raises(RecordError, match="naive"):
        rec.create_session("validation", **SNAPSHOT)
