"""Import: an export (folder or zip) back into the record, treated as untrusted input.

One path for ``station import`` and ``POST /api/v1/sessions/import``:

1. ``session.json`` is parsed and checked whole (``_format.py``): every key, type and unit, the ids,
   each capture's path exactly the export's. Then, before any write: the session is not in the record,
   its image folder does not exist, and every session it measures is.
2. Each image is read from the source (``_sources.py``: no links, bounded), checked against its
   sha256, decoded through the station's image front door (``station/imageio.py``: size caps, a
   PNG that decodes) and compared with its row (grey, width, height, dtype); then written, fsynced,
   into a new staging directory ``DATA/.import-<random>/`` inside the data directory.
3. One transaction inserts the rows; inside it, the staged folder is renamed to ``DATA/images/<id>``
   (a rename that never replaces anything) before the commit. A failing commit moves the folder back.

On any failure only the staging directory (which this import created) is removed: the import never
writes, renames or deletes a path it did not create, and a refused import leaves the record and the
data directory as they were.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import logging
import os
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import sqlalchemy as sa

from station.imageio import ImageFileError, ImageLimits, decode_image
from station.record import _images
from station.record._errors import ImportRefusedError, RecordError, RecordNotFoundError, RecordWriteError
from station.record._format import CaptureDoc, ExportDocument, parse_document
from station.record._protocol import RecordLike
from station.record._schema import captures, events, measurements, new_id, sessions, steps

if TYPE_CHECKING:
    from station.record._rows import SessionRow
    from station.record._sources import ExportSource

log = logging.getLogger(__name__)

STAGING_PREFIX = ".import-"
_BATCH = 500
_AT_FDCWD = -100
_RENAME_NOREPLACE = 1


def import_export(
    record: RecordLike, source: ExportSource, *, limits: ImageLimits | None = None
) -> SessionRow:
    """Import ``source`` into ``record`` (see the module notes); the session keeps its id.

    Raises
    ------
    ImportRefusedError
        The export is refused (the message names the field); nothing was written.
    RecordError
        The record could not take it (the database, a full disk); nothing was kept.
    """
    if record.read_only:
        raise RecordError(f"the record at {record.url} was opened read-only: this command does not write")
    doc = parse_document(source.document())
    sid = doc.session.id
    with contextlib.suppress(RecordNotFoundError):
        record.get_session(sid)
        raise ImportRefusedError(
            "session.json: session.id",
            f"session {sid} is already in the record at {record.url}",
            "importing it again would duplicate it",
        )
    target = record.data_dir / "images" / sid
    if os.path.lexists(target):
        raise ImportRefusedError(
            "session.json: session.id",
            f"{target} exists although the record has no session {sid}",
            "move that folder out of the data directory, then import again",
        )
    with record._read() as conn:
        _other_captures(conn, record, doc)  # refused before anything is written
    try:
        staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=record.data_dir))
    except OSError as exc:  # a full disk, a read-only directory
        raise RecordWriteError(str(record.data_dir / f"{STAGING_PREFIX}..."), exc) from exc
    try:
        folder = staging / sid
        folder.mkdir()
        for i, capture in enumerate(doc.captures):
            _stage_image(source, capture, i, folder, limits or ImageLimits())
        source.check_rest()
        _commit(record, doc, folder, target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)  # empty after a success: the folder was moved out
    return record.get_session(sid)


def _stage_image(source: ExportSource, c: CaptureDoc, i: int, folder: Path, limits: ImageLimits) -> None:
    field = f"session.json: captures[{i}].path"
    data = source.file(c.path, field, max_bytes=limits.max_bytes)
    actual = hashlib.sha256(data).hexdigest()
    if actual != c.sha256:
        raise ImportRefusedError(
            f"session.json: captures[{i}].sha256",
            f"{c.path} does not match its recorded sha256 (file {actual[:12]}..., recorded "
            f"{c.sha256[:12]}...)",
            "the export was changed or damaged: export the session again from its station",
        )
    try:
        loaded = decode_image(data, name=c.path, limits=limits)
    except ImageFileError as exc:
        raise ImportRefusedError(field, f"{c.path}: {exc.reason}") from None
    image = loaded.image
    if loaded.header.format != "PNG" or image.ndim != 2:
        raise ImportRefusedError(field, f"{c.path} is not a grey PNG, as every capture is stored")
    if (image.shape[1], image.shape[0], image.dtype.name) != (c.width, c.height, c.dtype):
        raise ImportRefusedError(
            field,
            f"{c.path} is {image.shape[1]}x{image.shape[0]} {image.dtype.name}, its row says "
            f"{c.width}x{c.height} {c.dtype}",
        )
    _images.write_atomic(folder / c.path.rsplit("/", 1)[1], data)


def _rename_noreplace(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst``, never replacing whatever ``dst`` may be (Linux ``renameat2``)."""
    libc = ctypes.CDLL(None, use_errno=True)
    rename2 = getattr(libc, "renameat2", None)
    if rename2 is not None:
        if rename2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _RENAME_NOREPLACE) == 0:
            return
        err = ctypes.get_errno()
        if err not in (errno.ENOSYS, errno.EINVAL):  # else: a kernel or file system without it
            raise OSError(err, os.strerror(err), str(dst))
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
    os.rename(src, dst)


def _commit(record: RecordLike, doc: ExportDocument, folder: Path, target: Path) -> None:
    """The rows in one transaction, the staged folder renamed into place just before its commit."""
    images = target.parent
    made_images = not images.exists()
    moved = False
    try:
        with record._write() as conn:
            _insert_rows(conn, record, doc)
            if made_images:
                images.mkdir()
            try:
                _rename_noreplace(folder, target)
            except OSError as exc:
                raise RecordError(
                    f"cannot move the imported images into {target}: {exc.strerror}; nothing was imported"
                ) from exc
            moved = True
            _images.fsync_dir(images)
    except BaseException:
        if moved:  # the commit failed: the folder goes back to the staging directory, removed with it
            try:
                _rename_noreplace(target, folder)
            except OSError as exc:
                log.error("the imported images stay in %s without rows: %s; remove that folder", target, exc)
        if made_images:
            with contextlib.suppress(OSError):
                images.rmdir()  # only if still empty: ours
        raise


def _other_captures(
    conn: sa.Connection, record: RecordLike, doc: ExportDocument
) -> dict[tuple[str, int, int], int]:
    """The record's ids of the other sessions' captures the document measures (a re-analysis)."""
    sid = doc.session.id
    found: dict[tuple[str, int, int], int] = {}
    for i, m in enumerate(doc.measurements):
        ref = m.capture
        key = (ref.session_id, ref.step_index, ref.frame_index)
        if ref.session_id == sid or key in found:
            continue
        cid = conn.execute(
            sa.select(captures.c.id).where(
                (captures.c.session_id == key[0])
                & (captures.c.step_index == key[1])
                & (captures.c.frame_index == key[2])
            )
        ).scalar_one_or_none()
        if cid is None:
            raise ImportRefusedError(
                f"session.json: measurements[{i}].capture",
                f"session {sid} measures step {key[1]} frame {key[2]} of session {key[0]}, which is not in "
                f"the record at {record.url}",
                f"import session {key[0]} first",
            )
        found[key] = int(cid)
    return found


def _insert_rows(conn: sa.Connection, record: RecordLike, doc: ExportDocument) -> None:
    s = doc.session
    sid = s.id
    conn.execute(sessions.insert().values(**s.model_dump()))
    step_rows = [
        {
            "session_id": sid,
            "step_index": st.index,
            "name": st.name,
            "state": st.state,
            "data": st.data,
            "started_at": st.started_at,
            "finished_at": st.finished_at,
        }
        for st in doc.steps
    ]
    if step_rows:
        conn.execute(steps.insert(), step_rows)
    event_rows = [
        {"session_id": sid, "seq": e.seq, "time": e.time, "type": e.type, "data": e.data} for e in doc.events
    ]
    for i in range(0, len(event_rows), _BATCH):
        conn.execute(events.insert(), event_rows[i : i + _BATCH])
    ids = _other_captures(conn, record, doc)  # again, inside the transaction
    for c in doc.captures:
        values: dict[str, Any] = c.model_dump(exclude={"id"})
        values["timestamp_s"] = float(c.timestamp_s)
        values["z_mm"] = None if c.z_mm is None else float(c.z_mm)
        ids[(sid, c.step_index, c.frame_index)] = new_id(
            conn.execute(captures.insert().values(session_id=sid, **values))
        )
    rows = [
        {
            "session_id": sid,
            "capture_id": ids[(m.capture.session_id, m.capture.step_index, m.capture.frame_index)],
            "params_hash": m.params_hash,
            "software": m.software,
            "ok": m.ok,
            "result": m.result,
        }
        for m in doc.measurements
    ]
    for i in range(0, len(rows), _BATCH):
        conn.execute(measurements.insert(), rows[i : i + _BATCH])
