"""A session exported as a folder (JSON + CSV + images) and imported back is the same session."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest

from station.record import Record, RecordError
from tests.record.conftest import NewUrl, StepClock
from tests.record.test_sessions import SNAPSHOT


def _fill(rec: Record) -> str:
    s = rec.create_session("validation", **SNAPSHOT)
    rec.set_state(s.id, "running")
    rng = np.random.default_rng(3)
    for step in range(3):
        rec.begin_step(s.id, step, f"position {step}", {"target_um": [step * 5.08, 0.0]})
        rec.add_event(s.id, "step_started", {"index": step})
        for frame in range(2):
            image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16]
            if step == 2:
                image = rng.integers(0, np.iinfo(np.uint16).max, size=(40, 56), dtype=np.uint16)
            else:
                image = rng.integers(0, np.iinfo(np.uint8).max, size=(40, 56), dtype=np.uint8)
            cap = rec.save_capture(s.id, step, frame, image, timestamp_s=step + frame / 10, meta={"f": frame})
            rec.add_event(s.id, "image_captured", {"capture_id": cap.id})
            result = {"ok": True, "center_px": [20.0 + step, 28.0], "center_mm": [0.001 * step, 0.0]}
            rec.add_measurement(s.id, cap.id, result, params={"mode": "precise"}, software="0.1.0")
        rec.finish_step(s.id, step)
    failed_cap = rec.captures(s.id)[0]
    rec.add_measurement(
        s.id, failed_cap.id, {"ok": False, "error": "no cross", "code": "x"}, params={}, software="0.1.0"
    )
    rec.set_results(s.id, {"mean_um": 0.05, "max_um": 0.12})
    rec.set_state(s.id, "succeeded")
    return s.id


def _capture_key(rec: Record, capture_id: int) -> tuple[int, int]:
    cap = rec.capture(capture_id)
    return (cap.step_index, cap.frame_index)


def test_export_then_import_gives_the_same_session(tmp_path: Path, new_url: NewUrl) -> None:
    with (
        Record(tmp_path / "a", new_url(), clock=StepClock()) as src,
        Record(tmp_path / "b", new_url(), clock=StepClock()) as dst,
    ):
        other = dst.create_session("repeatability", **SNAPSHOT)  # the target record has its own rows
        dst.add_event(other.id, "state", {"state": "running"})
        sid = _fill(src)
        folder = src.export_session(sid[:6], tmp_path / "out")
        assert folder == tmp_path / "out" / sid
        assert sorted(p.name for p in folder.iterdir()) == [
            "captures.csv",
            "images",
            "measurements.csv",
            "session.json",
        ]

        imported = dst.import_session(folder)
        assert imported == src.get_session(sid)
        assert dst.steps(sid) == src.steps(sid)

        def events(rec: Record) -> list[tuple[object, ...]]:
            return [(e.seq, e.time, e.type, e.data) for e in rec.events(sid)]

        assert events(dst) == events(src)
        assert [e.id for e in dst.events(sid)] == sorted(e.id for e in dst.events(sid))

        def captures(rec: Record) -> list[dict[str, object]]:
            return [{k: v for k, v in c.__dict__.items() if k != "id"} for c in rec.captures(sid)]

        assert captures(dst) == captures(src)
        for a, b in zip(src.captures(sid), dst.captures(sid), strict=True):
            assert (dst.data_dir / b.path).read_bytes() == (src.data_dir / a.path).read_bytes()
            np.testing.assert_array_equal(dst.load_image(b), src.load_image(a))

        def measurements(rec: Record) -> list[tuple[object, ...]]:
            return [
                (_capture_key(rec, m.capture_id), m.params_hash, m.software, m.ok, m.result)
                for m in rec.measurements(sid)
            ]

        assert measurements(dst) == measurements(src)
        assert dst.get_session(other.id).kind == "repeatability"

        with pytest.raises(RecordError, match=f"session {sid} is already in the record"):
            dst.import_session(folder)


def test_export_folder_is_readable_without_the_station(tmp_path: Path) -> None:
    with Record(tmp_path / "a") as rec:
        sid = _fill(rec)
        folder = rec.export_session(sid, tmp_path / "out")
        doc = json.loads((folder / "session.json").read_text())
        assert doc["format"] == "station-session"
        assert doc["session"]["id"] == sid
        assert doc["session"]["results"] == {"mean_um": 0.05, "max_um": 0.12}
        assert [len(doc[k]) for k in ("steps", "events", "captures", "measurements")] == [3, 9, 6, 7]
        with (folder / "captures.csv").open() as f:
            rows = list(csv.DictReader(f))
        assert [r["path"] for r in rows] == [c.path for c in rec.captures(sid)]
        assert all((folder / r["path"]).is_file() for r in rows)
        with (folder / "measurements.csv").open() as f:
            rows = list(csv.DictReader(f))
        assert [r["ok"] for r in rows] == ["True"] * 6 + ["False"]
        assert rows[2]["center_px_x"] == "21.0"
        with pytest.raises(RecordError, match="already exists"):
            rec.export_session(sid, tmp_path / "out")


def test_import_refuses_changed_images_and_leaves_nothing(tmp_path: Path) -> None:
    with Record(tmp_path / "a") as src, Record(tmp_path / "b") as dst:
        sid = _fill(src)
        folder = src.export_session(sid, tmp_path / "out")
        last = src.captures(sid)[-1]
        (folder / last.path).write_bytes(b"\x89PNG not the image")
        with pytest.raises(RecordError, match="does not match its recorded sha256"):
            dst.import_session(folder)
        assert dst.list_sessions() == []
        assert not (dst.data_dir / "images" / sid).exists() or not any(
            (dst.data_dir / "images" / sid).iterdir()
        )


def test_import_of_a_folder_that_is_not_an_export(tmp_path: Path) -> None:
    with Record(tmp_path / "a") as rec:
        with pytest.raises(RecordError, match=r"no session\.json"):
            rec.import_session(tmp_path)
        (tmp_path / "session.json").write_text('{"format": "other"}')
        with pytest.raises(RecordError, match="format: is not 'station-session'"):
            rec.import_session(tmp_path)
