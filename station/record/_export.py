"""A session as a self-contained folder, and back: ``<id>/session.json``, two CSV files, ``images/``.

``session.json`` holds everything: the session row, its steps, events, captures and measurements
(``format``/``format_version`` say what it is). ``captures.csv`` and ``measurements.csv`` are the same
rows flattened for a spreadsheet; ``images/<id>/...`` the PNG files, byte for byte.

Import gives back the same session: same id, same row contents, same image bytes. The ids the
database assigns (event, capture and measurement ids) are new in the importing record, since another
record has its own; events keep their ``seq`` and order, measurements point at the imported captures.
A measurement of another session's capture (a re-analysis) needs that session in the record first.
Rows are streamed out; an import reads ``session.json`` whole (rows only, no images: a few MB).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
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
from station.record._errors import RecordError, RecordNotFoundError
from station.record._schema import captures, events, measurements, new_id, sessions, steps

if TYPE_CHECKING:
    from station.record._record import Record
    from station.record._rows import SessionRow

FORMAT = "station-session"
FORMAT_VERSION = 1
_BATCH = 500


def _iso(value: datetime | None) -> str | None:
    return None if value is None else value.isoformat()


def _time(value: str | None) -> datetime | None:
    return None if value is None else datetime.fromisoformat(value)


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
    data = src.read_bytes()
    if hashlib.sha256(data).hexdigest() != sha256:
        raise RecordError(
            f"capture image {src} does not match its recorded sha256: restore the original before "
            "exporting or importing"
        )
    _images.write_atomic(dst, data)


def export_session(record: Record, session_id: str, out_dir: Path) -> Path:
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


def _export_into(record: Record, session: SessionRow, work: Path) -> None:
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
            _copy_image(data_dir / r.path, work / r.path, r.sha256)


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


def _load(folder: Path) -> dict[str, Any]:
    path = folder / "session.json"
    try:
        with path.open(encoding="utf-8") as f:
            doc = json.load(f)
    except FileNotFoundError:
        raise RecordError(f"{folder} is not an exported session: it has no session.json") from None
    except (OSError, ValueError) as exc:
        raise RecordError(f"cannot read {path}: {exc}") from exc
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise RecordError(f"{path} is not a station session export (format {FORMAT!r} expected)")
    if doc.get("format_version") != FORMAT_VERSION:
        raise RecordError(
            f"{path} has export format version {doc.get('format_version')}; this station reads "
            f"version {FORMAT_VERSION}: update the station software"
        )
    return doc


def import_session(record: Record, folder: Path) -> SessionRow:
    doc = _load(folder)
    s = doc["session"]
    sid = s["id"]
    with contextlib.suppress(RecordNotFoundError):
        record.get_session(sid)
        raise RecordError(
            f"session {sid} is already in the record at {record.url}: importing it again would duplicate it"
        )
    written: list[Path] = []
    try:
        for c in doc["captures"]:
            dst = record.data_dir / c["path"]
            _copy_image(folder / c["path"], dst, c["sha256"])
            written.append(dst)
        _insert_rows(record, doc)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    return record.get_session(sid)


def _insert_rows(record: Record, doc: dict[str, Any]) -> None:
    s = doc["session"]
    sid = s["id"]
    with record._write() as conn:
        conn.execute(
            sessions.insert().values(
                {**s, "created_at": _time(s["created_at"]), "updated_at": _time(s["updated_at"])}
            )
        )
        step_rows = [
            {
                "session_id": sid,
                "step_index": st["index"],
                "name": st["name"],
                "state": st["state"],
                "data": st["data"],
                "started_at": _time(st["started_at"]),
                "finished_at": _time(st["finished_at"]),
            }
            for st in doc["steps"]
        ]
        if step_rows:
            conn.execute(steps.insert(), step_rows)
        event_rows = [
            {
                "session_id": sid,
                "seq": e["seq"],
                "time": _time(e["time"]),
                "type": e["type"],
                "data": e["data"],
            }
            for e in doc["events"]
        ]
        for i in range(0, len(event_rows), _BATCH):
            conn.execute(events.insert(), event_rows[i : i + _BATCH])
        new_ids: dict[tuple[str, int, int], int] = {}
        for c in doc["captures"]:
            values = {k: v for k, v in c.items() if k != "id"}
            done = conn.execute(captures.insert().values(session_id=sid, **values))
            new_ids[(sid, c["step_index"], c["frame_index"])] = new_id(done)
        rows = []
        for m in doc["measurements"]:
            ref = m["capture"]
            key = (ref["session_id"], ref["step_index"], ref["frame_index"])
            if key not in new_ids:
                new_ids[key] = _find_capture(conn, record, sid, key)
            rows.append(
                {
                    "session_id": sid,
                    "capture_id": new_ids[key],
                    "params_hash": m["params_hash"],
                    "software": m["software"],
                    "ok": m["ok"],
                    "result": m["result"],
                }
            )
        for i in range(0, len(rows), _BATCH):
            conn.execute(measurements.insert(), rows[i : i + _BATCH])


def _find_capture(conn: sa.Connection, record: Record, sid: str, key: tuple[str, int, int]) -> int:
    found = conn.execute(
        sa.select(captures.c.id).where(
            (captures.c.session_id == key[0])
            & (captures.c.step_index == key[1])
            & (captures.c.frame_index == key[2])
        )
    ).scalar_one_or_none()
    if found is None:
        raise RecordError(
            f"session {sid} measures step {key[1]} frame {key[2]} of session {key[0]}, which is not in "
            f"the record at {record.url}: import session {key[0]} first"
        )
    return int(found)
