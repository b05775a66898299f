"""A session as a self-contained folder, and back: ``<id>/session.json``, two CSV files, ``images/``.

``session.json`` holds everything: the session row, its steps, events, captures and measurements
(``format``/``format_version`` say what it is). ``captures.csv`` and ``measurements.csv`` are the same
rows flattened for a spreadsheet; ``images/<id>/...`` the PNG files, byte for byte.

Import (``_import.py``) gives back the same session: same id, same row contents, same image bytes.
The format is ``_format.py``'s model. Rows are streamed out; every image is checked against its
sha256 on the way.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import uuid
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import sqlalchemy as sa

from station.record import _images
from station.record._engine import head_revision
from station.record._errors import RecordError
from station.record._format import FORMAT, FORMAT_VERSION, capture_file
from station.record._protocol import RecordLike
from station.record._schema import captures, events, measurements, steps

if TYPE_CHECKING:
    from station.record._rows import SessionRow

_BATCH = 500


def _iso(value: datetime | None) -> str | None:
    return None if value is None else value.isoformat()


def _stream(conn: sa.Connection, query: sa.Select[Any]) -> Iterator[sa.Row[Any]]:
    yield from conn.execution_options(yield_per=_BATCH).execute(query)


def _write_array(f: IO[str], name: str, items: Iterator[dict[str, Any]]) -> None:
    f.write(f',\n "{name}": [')
    for i, item in enumerate(items):
        f.write(("\n  " if i == 0 else ",\n  ") + json.dumps(item, allow_nan=False))
    f.write("\n ]")


def _session_dict(s: SessionRow) -> dict[str, Any]:
    d = dict(s.__dict__)
    d["created_at"] = _iso(s.created_at)
    d["updated_at"] = _iso(s.updated_at)
    return d


def _copy_image(src: Path, dst: Path, sha256: str) -> None:
    data = _images.read_bytes_checked(src, sha256)
    _images.write_atomic(dst, data)


def export_session(record: RecordLike, session_id: str, out_dir: Path) -> Path:
    session = record.get_session(session_id)
    final = out_dir / session.id
    if final.exists():
        raise RecordError(f"{final} already exists: export into another folder or remove it first")
    out_dir.mkdir(parents=True, exist_ok=True)
    work = out_dir / f".{session.id}.partial-{uuid.uuid4().hex[:6]}"
    work.mkdir()
    try:
        _export_into(record, session, work)
        os.replace(work, final)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    return final


def _export_into(record: RecordLike, session: SessionRow, work: Path) -> None:
    sid = session.id
    step_q = sa.select(steps).where(steps.c.session_id == sid).order_by(steps.c.step_index)
    event_q = sa.select(events).where(events.c.session_id == sid).order_by(events.c.id)
    capture_q = (
        sa.select(captures)
        .where(captures.c.session_id == sid)
        .order_by(captures.c.step_index, captures.c.frame_index)
    )
    cap = captures.alias("cap")
    measurement_q = (
        sa.select(
            measurements,
            cap.c.session_id.label("cap_session"),
            cap.c.step_index.label("cap_step"),
            cap.c.frame_index.label("cap_frame"),
        )
        .join(cap, cap.c.id == measurements.c.capture_id)
        .where(measurements.c.session_id == sid)
        .order_by(measurements.c.id)
    )
    with record.engine.connect() as conn, conn.begin():
        with (work / "session.json").open("w", encoding="utf-8") as f:
            header = {"format": FORMAT, "format_version": FORMAT_VERSION, "schema_revision": head_revision()}
            f.write("{\n" + json.dumps(header)[1:-1].replace(", ", ",\n "))
            f.write(',\n "session": ' + json.dumps(_session_dict(session), allow_nan=False))
            _write_array(
                f,
                "steps",
                (
                    {
                        "index": r.step_index,
                        "name": r.name,
                        "state": r.state,
                        "data": r.data,
                        "started_at": _iso(r.started_at),
                        "finished_at": _iso(r.finished_at),
                    }
                    for r in _stream(conn, step_q)
                ),
            )
            _write_array(
                f,
                "events",
                (
                    {"id": r.id, "seq": r.seq, "time": _iso(r.time), "type": r.type, "data": r.data}
                    for r in _stream(conn, event_q)
                ),
            )
            _write_array(f, "captures", (_capture_dict(r) for r in _stream(conn, capture_q)))
            _write_array(f, "measurements", (_measurement_dict(r) for r in _stream(conn, measurement_q)))
            f.write("\n}\n")
        _write_captures_csv(conn, capture_q, work / "captures.csv", record.data_dir, work)
        _write_measurements_csv(conn, measurement_q, work / "measurements.csv")


def _capture_dict(r: sa.Row[Any]) -> dict[str, Any]:
    return {
        "id": r.id,
        "step_index": r.step_index,
        "frame_index": r.frame_index,
        "path": r.path,
        "width": r.width,
        "height": r.height,
        "dtype": r.dtype,
        "sha256": r.sha256,
        "timestamp_s": r.timestamp_s,
        "meta": r.meta,
        "z_mm": r.z_mm,
    }


def _measurement_dict(r: sa.Row[Any]) -> dict[str, Any]:
    return {
        "id": r.id,
        "capture_id": r.capture_id,
        "capture": {"session_id": r.cap_session, "step_index": r.cap_step, "frame_index": r.cap_frame},
        "params_hash": r.params_hash,
        "software": r.software,
        "ok": r.ok,
        "result": r.result,
    }


CAPTURE_COLUMNS = [
    "id", "step_index", "frame_index", "path", "width", "height", "dtype", "sha256", "timestamp_s", "meta",
    "z_mm",
]  # fmt: skip
MEASUREMENT_COLUMNS = [
    "id", "capture_id", "capture_session_id", "step_index", "frame_index", "ok", "center_px_x",
    "center_px_y", "center_mm_x", "center_mm_y", "error", "code", "params_hash", "software",
]  # fmt: skip


def _write_captures_csv(
    conn: sa.Connection, query: sa.Select[Any], path: Path, data_dir: Path, work: Path
) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(CAPTURE_COLUMNS)
        for r in _stream(conn, query):
            d = _capture_dict(r)
            writer.writerow([json.dumps(d[c]) if c == "meta" else d[c] for c in CAPTURE_COLUMNS])
            src = capture_file(data_dir, r.session_id, r.step_index, r.frame_index, r.path)
            _copy_image(src, work / r.path, r.sha256)


def _pair(value: Any, i: int) -> Any:
    return value[i] if isinstance(value, list) and len(value) == 2 else None


def _write_measurements_csv(conn: sa.Connection, query: sa.Select[Any], path: Path) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(MEASUREMENT_COLUMNS)
        for r in _stream(conn, query):
            res = r.result
            writer.writerow(
                [
                    r.id, r.capture_id, r.cap_session, r.cap_step, r.cap_frame, r.ok,
                    _pair(res.get("center_px"), 0), _pair(res.get("center_px"), 1),
                    _pair(res.get("center_mm"), 0), _pair(res.get("center_mm"), 1),
                    res.get("error"), res.get("code"), r.params_hash, r.software,
                ]
            )  # fmt: skip
