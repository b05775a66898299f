"""Captures: lossless atomic PNG files, checked on load; measurements without point arrays."""

from __future__ import annotations

import errno
import hashlib
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
from sqlalchemy import event as sa_event

from station.record import MAX_POINTS, Record, RecordError, RecordWriteError, _images, params_hash
from tests.record.test_sessions import SNAPSHOT


def _frame(dtype: type[np.integer], seed: int = 0) -> np.ndarray:
    info = np.iinfo(dtype)
    rng = np.random.default_rng(seed)
    return rng.integers(0, int(info.max) + 1, size=(48, 64), dtype=dtype)


def test_stores_png_file_and_row(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    image = _frame(np.uint8)
    row = record.save_capture(s.id, 3, 1, image, timestamp_s=12.5, meta={"pose": [1.0, 2.0]})
    assert row.path == f"images/{s.id}/00003-01.png"
    assert (row.width, row.height, row.dtype) == (64, 48, "uint8")
    stored = record.data_dir / row.path
    assert stored.read_bytes().startswith(b"\x89PNG")
    assert hashlib.sha256(stored.read_bytes()).hexdigest() == row.sha256
    assert record.captures(s.id) == [row]
    assert record.captures(s.id, step_index=3) == [row]
    assert record.captures(s.id, step_index=2) == []
    assert record.capture(row.id) == row
    assert list(stored.parent.iterdir()) == [stored]  # no temporary file left


def test_16_bit_round_trip_is_exact(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    image = _frame(np.uint16, seed=1)
    row = record.save_capture(s.id, 0, 0, image, timestamp_s=0.0, meta={})
    assert row.dtype == "uint16"
    back = record.load_image(row)
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, image)
    on_disk = cv2.imread(str(record.data_dir / row.path), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(on_disk, image)


def test_changed_file_is_refused_on_load(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    row = record.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta={})
    path = record.data_dir / row.path
    tampered = _frame(np.uint8, seed=9)
    path.write_bytes(cv2.imencode(".png", tampered)[1].tobytes())
    with pytest.raises(RecordError, match=rf"{row.path}.*changed since it was recorded"):
        record.load_image(row)
    path.unlink()
    with pytest.raises(RecordError, match="cannot be read"):
        record.load_image(row)


def test_disk_full_leaves_no_file_no_temp_and_no_row(record: Record, monkeypatch: pytest.MonkeyPatch) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    first = record.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta={})
    real_write_all = _images._write_all

    def half_then_enospc(fd: int, data: bytes) -> None:
        real_write_all(fd, data[: len(data) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(_images, "_write_all", half_then_enospc)
    with pytest.raises(RecordWriteError, match=r"00000-01\.png: No space left on device") as err:
        record.save_capture(s.id, 0, 1, _frame(np.uint8, 2), timestamp_s=1.0, meta={})
    assert err.value.errno == errno.ENOSPC
    assert record.captures(s.id) == [first]
    assert sorted(p.name for p in (record.data_dir / "images" / s.id).iterdir()) == ["00000-00.png"]
    monkeypatch.undo()
    retry = record.save_capture(s.id, 0, 1, _frame(np.uint8, 2), timestamp_s=1.0, meta={})
    np.testing.assert_array_equal(record.load_image(retry), _frame(np.uint8, 2))


def test_fsync_failure_is_a_write_error_too(record: Record, monkeypatch: pytest.MonkeyPatch) -> None:
    s = record.create_session("validation", **SNAPSHOT)

    def eio(fd: int) -> None:
        raise OSError(errno.EIO, os.strerror(errno.EIO))

    monkeypatch.setattr(_images.os, "fsync", eio)
    with pytest.raises(RecordWriteError, match="Input/output error"):
        record.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta={})
    monkeypatch.undo()
    assert record.captures(s.id) == []
    assert list((record.data_dir / "images" / s.id).iterdir()) == []


def test_a_frame_is_never_overwritten(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    row = record.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta={})
    before = (record.data_dir / row.path).read_bytes()
    with pytest.raises(RecordError, match="already has step 0 frame 0"):
        record.save_capture(s.id, 0, 0, _frame(np.uint8, 5), timestamp_s=1.0, meta={})
    assert (record.data_dir / row.path).read_bytes() == before


@pytest.mark.parametrize(
    ("image", "message"),
    [
        (np.zeros((4, 4, 3), np.uint8), "2-D uint8 or uint16"),
        (np.zeros((4, 4), np.float32), "2-D uint8 or uint16"),
        (np.zeros((0, 4), np.uint8), "empty"),
    ],
)
def test_rejects_images_the_camera_does_not_give(tmp_path: Path, image: np.ndarray, message: str) -> None:
    with Record(tmp_path) as rec:
        s = rec.create_session("validation", **SNAPSHOT)
        with pytest.raises(ValueError, match=message):
            rec.save_capture(s.id, 0, 0, image, timestamp_s=0.0, meta={})
        assert rec.captures(s.id) == []


def test_measurement_keeps_the_json_object_without_point_arrays(record: Record) -> None:
    s = record.create_session("validation", **SNAPSHOT)
    cap = record.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta={})
    result = {
        "file": cap.path,
        "ok": True,
        "center_px": [320.25, 240.5],
        "center_mm": [0.01, -0.02],
        "corners_px": [[1.0, 2.0]] * 4,
        "lines": [[1.0, 0.0, 3.0]] * 4,
        "edge_points": np.zeros((500, 2)),
        "diagnostics": {"rms_px": 0.02, "inlier_points": [[0, 0]] * (MAX_POINTS + 1), "few_points": [[1, 1]]},
    }
    params = {"mode": "precise", "testwidth": 5}
    row = record.add_measurement(s.id, cap.id, result, params=params, software="station 0.1.0")
    assert "edge_points" not in row.result
    assert row.result["diagnostics"] == {"rms_px": 0.02, "few_points": [[1, 1]]}
    assert row.result["center_px"] == [320.25, 240.5]
    assert row.ok is True
    assert row.params_hash == params_hash({"testwidth": 5, "mode": "precise"})
    assert record.measurements(s.id) == [row]
    failed = record.add_measurement(
        s.id, cap.id, {"ok": False, "error": "no cross", "code": "no_cross"}, params=params, software="x"
    )
    assert failed.ok is False
    assert record.measurements(s.id) == [row, failed]
    with pytest.raises(RecordError, match="no capture 999999"):
        record.add_measurement(s.id, 999999, {"ok": True}, params=params, software="x")


def test_database_full_is_a_record_error_and_keeps_what_was_committed(tmp_path: Path) -> None:
    """SQLite's own disk-full (SQLITE_FULL, simulated by capping the file at its size): a clean
    error naming the cause, no image file left without its row, and earlier rows intact."""
    with Record(tmp_path) as rec:
        s = rec.create_session("validation", **SNAPSHOT)
        kept = rec.add_event(s.id, "state", {"state": "running"})
        with rec.engine.connect() as conn:
            pages = conn.exec_driver_sql("PRAGMA page_count").scalar()
        sa_event.listen(rec.engine, "connect", lambda c, _r: c.execute(f"PRAGMA max_page_count={pages}"))
        rec.engine.dispose()
        big = {"note": "x" * 20000}
        with pytest.raises(RecordError, match=r"cannot write to the record at .*full"):
            rec.add_event(s.id, "pad", big)
        with pytest.raises(RecordError, match="full"):
            rec.save_capture(s.id, 0, 0, _frame(np.uint8), timestamp_s=0.0, meta=big)
        assert not (rec.data_dir / "images" / s.id / "00000-00.png").exists()
        assert rec.events(s.id) == [kept]
        assert rec.captures(s.id) == []


def test_the_latest_capture_and_its_measurement_are_read_alone(record: Record) -> None:
    """The live view's picture: the newest stored capture (a resume's check, numbered after the plan's
    steps, is not the latest once the session goes on) and that session's newest measurement of it, each
    one row asked for, however many the session holds."""
    s = record.create_session("validation", **SNAPSHOT)
    assert record.latest_capture(s.id) is None
    check = record.save_capture(s.id, 1_000_000, 0, _frame(np.uint8), timestamp_s=1.0, meta={})
    later = [
        record.save_capture(s.id, k, 0, _frame(np.uint8, k), timestamp_s=2.0 + k, meta={}) for k in (3, 4)
    ]
    assert record.latest_measurement(s.id, later[-1].id) is None  # not measured yet
    params = {"mode": "precise"}
    first = record.add_measurement(s.id, later[-1].id, {"ok": True, "n": 1}, params=params, software="t")
    again = record.add_measurement(s.id, later[-1].id, {"ok": True, "n": 2}, params=params, software="t")
    other = record.create_session("reanalyse", **SNAPSHOT, parent_id=s.id)  # measures s's captures again
    record.add_measurement(other.id, later[-1].id, {"ok": False, "n": 3}, params=params, software="t")

    statements: list[str] = []

    def seen(_c: object, _cur: object, statement: str, *_: object) -> None:
        statements.append(statement)

    sa_event.listen(record.engine, "before_cursor_execute", seen)
    try:
        assert record.latest_capture(s.id) == later[-1]
        assert record.latest_measurement(s.id, later[-1].id) == again
        theirs = record.latest_measurement(other.id, later[-1].id)
    finally:
        sa_event.remove(record.engine, "before_cursor_execute", seen)
    assert theirs is not None
    assert theirs.result["n"] == 3  # each session's own measurement
    assert first.id < again.id
    assert check.id < later[0].id
    selects = [st for st in statements if st.lstrip().upper().startswith("SELECT")]
    assert len(selects) == 3
    assert all("LIMIT" in st.upper() for st in selects)
