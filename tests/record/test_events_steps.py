"""Events (station-wide ids, per-session seq) and steps (resume bookkeeping)."""

from __future__ import annotations

import numpy as np
import pytest

from station.record import Record, RecordError, RecordNotFoundError
from tests.record.test_sessions import SNAPSHOT


def test_event_ids_increase_station_wide_and_seq_counts_per_session(record: Record) -> None:
    a = record.create_session("validation", **SNAPSHOT)
    b = record.create_session("repeatability", **SNAPSHOT)
    made = [
        record.add_event(a.id, "state", {"state": "running"}),
        record.add_event(b.id, "state", {"state": "running"}),
        record.add_event(a.id, "step_started", {"index": 0}),
        record.add_event(a.id, "image_captured", {"capture_id": 1}),
        record.add_event(b.id, "warning", {"text": "slow"}),
    ]
    ids = [e.id for e in made]
    assert ids == sorted(ids)
    assert len(set(ids)) == len(ids)
    assert [e.seq for e in made] == [1, 1, 2, 3, 2]
    assert record.events() == made
    assert record.events(a.id) == [made[0], made[2], made[3]]
    assert record.events(after_id=made[1].id) == made[2:]
    assert record.events(a.id, after_id=made[0].id, limit=1) == [made[2]]
    assert made[2].time > made[0].time


def test_last_event_is_the_newest_of_its_type_whatever_session(record: Record) -> None:
    assert record.last_event("table_content") is None
    older = record.create_session("validation", **SNAPSHOT)
    newer = record.create_session("calibration", **SNAPSHOT)
    record.add_event(newer.id, "table_content", {"content": "cross"})
    resumed = record.add_event(older.id, "table_content", {"content": "ruler"})  # the older one resumed
    record.add_event(newer.id, "state", {"state": "running"})
    assert record.last_event("table_content") == resumed
    assert record.last_event("state") is not None
    assert record.last_event("state").session_id == newer.id  # type: ignore[union-attr]
    assert record.last_event("no_such_type") is None


def test_event_data_comes_back_as_written(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    written = record.add_event(s.id, "measurement", {"center_mm": np.array([0.1, -0.2]), "n": np.int64(3)})
    assert written.data == {"center_mm": [0.1, -0.2], "n": 3}
    assert record.events(s.id) == [written]


def test_event_for_unknown_session_is_refused(record: Record) -> None:
    with pytest.raises(RecordNotFoundError):
        record.add_event("0123456789ab", "state", {})
    assert record.events() == []


def test_steps_and_last_completed_step(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    assert record.last_completed_step(s.id) is None
    record.begin_step(s.id, 0, "reference", {"pose": [0, 0]})
    assert record.last_completed_step(s.id) is None
    record.finish_step(s.id, 0, data={"center_mm": [0.0, 0.0]})
    record.begin_step(s.id, 1, "position 1")
    record.finish_step(s.id, 1)
    record.begin_step(s.id, 2, "position 2")
    assert record.last_completed_step(s.id) == 1
    rows = record.steps(s.id)
    assert [(r.index, r.name, r.state) for r in rows] == [
        (0, "reference", "done"),
        (1, "position 1", "done"),
        (2, "position 2", "started"),
    ]
    assert rows[0].data == {"pose": [0, 0], "center_mm": [0.0, 0.0]}
    assert rows[0].finished_at is not None
    assert rows[0].finished_at > rows[0].started_at
    assert rows[2].finished_at is None
    record.finish_step(s.id, 2, state="failed", data={"error": "controller error 12"})
    assert record.steps(s.id)[2].state == "failed"
    assert record.last_completed_step(s.id) == 1


def test_rebeginning_a_step_resets_it_and_keeps_its_partial_captures(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    frame = np.full((64, 80), 7, np.uint8)
    record.begin_step(s.id, 0, "reference")
    kept = record.save_capture(s.id, 0, 0, frame, timestamp_s=0.0, meta={})
    record.finish_step(s.id, 0)
    record.begin_step(s.id, 1, "position 1")
    partial = record.save_capture(s.id, 1, 0, frame, timestamp_s=1.0, meta={})
    record.add_measurement(s.id, partial.id, {"ok": True}, params={}, software="t")
    # the process dies here; resume begins step 1 again
    record.begin_step(s.id, 1, "position 1", {"resumed": True})
    step = record.steps(s.id)[1]
    assert (step.state, step.data, step.finished_at) == ("started", {"resumed": True}, None)
    assert record.captures(s.id) == [kept, partial]  # nothing captured is lost
    assert len(record.measurements(s.id)) == 1
    assert (record.data_dir / partial.path).exists()
    with pytest.raises(RecordError, match="never overwritten"):
        record.save_capture(s.id, 1, 0, frame, timestamp_s=2.0, meta={})
    again = record.save_capture(s.id, 1, 1000, frame, timestamp_s=2.0, meta={})  # the next attempt
    assert record.load_image(again).tolist() == frame.tolist()


def test_finish_needs_a_begun_step_and_a_final_state(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    with pytest.raises(RecordError, match="no step 4: begin_step it first"):
        record.finish_step(s.id, 4)
    record.begin_step(s.id, 4, "x")
    with pytest.raises(ValueError, match="'done' or 'failed'"):
        record.finish_step(s.id, 4, state="started")
