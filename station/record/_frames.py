"""The record's frames: capture images (lossless PNG files beside the database) and their measurements.

A mixin of :class:`station.record.Record` (``_record.py``), which gives it the data directory and the
record's transactions: one concept per module, one class for the record's users.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import sqlalchemy as sa

from station.record import _images
from station.record._errors import RecordError
from station.record._format import capture_file, capture_path
from station.record._json import json_object, params_hash, strip_point_arrays
from station.record._rows import CaptureRow, MeasurementRow, capture_row, measurement_row
from station.record._schema import captures, measurements, new_id


class FramesMixin:
    """Captures and measurements of :class:`station.record.Record`."""

    _data_dir: Path

    if TYPE_CHECKING:

        @property
        def url(self) -> str: ...

        def _read(self) -> AbstractContextManager[sa.Connection]: ...

        def _write(self) -> AbstractContextManager[sa.Connection]: ...

        def _require_session(self, conn: sa.Connection, session_id: str, *, lock: bool = False) -> None: ...

    # -- captures --------------------------------------------------------------------------------
    def save_capture(
        self,
        session_id: str,
        step_index: int,
        frame_index: int,
        image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16],
        *,
        timestamp_s: float,
        meta: Mapping[str, Any],
        z_mm: float | None = None,
    ) -> CaptureRow:
        """Store a frame as a lossless PNG (atomically, durably), then its row.

        ``z_mm``: the distance sensor's reading with the frame (mm), if any.

        Raises
        ------
        RecordWriteError
            The file could not be written (disk full ...): no file, no row.
        """
        image = _images.check_image(image)
        if step_index < 0 or frame_index < 0:
            raise ValueError(f"step and frame indices must be >= 0, not {step_index}, {frame_index}")
        if z_mm is not None and not math.isfinite(z_mm):
            raise ValueError(f"z_mm must be a finite distance in mm or None, not {z_mm!r}")
        meta_value = json_object(meta, "meta")
        rel = capture_path(session_id, step_index, frame_index)
        with self._read() as conn:
            self._require_session(conn, session_id)
            taken = conn.execute(
                sa.select(captures.c.id).where(
                    (captures.c.session_id == session_id)
                    & (captures.c.step_index == step_index)
                    & (captures.c.frame_index == frame_index)
                )
            ).first()
        if taken is not None:
            raise RecordError(
                f"session {session_id} already has step {step_index} frame {frame_index} (capture "
                f"{taken.id}); frames are never overwritten: re-begin the step to capture it again"
            )
        data = _images.encode_png(image)
        sha = hashlib.sha256(data).hexdigest()
        path = self._data_dir / rel
        _images.write_atomic(path, data)
        del data
        values: dict[str, Any] = {
            "session_id": session_id,
            "step_index": step_index,
            "frame_index": frame_index,
            "path": rel,
            "width": int(image.shape[1]),
            "height": int(image.shape[0]),
            "dtype": image.dtype.name,
            "sha256": sha,
            "timestamp_s": float(timestamp_s),
            "meta": meta_value,
            "z_mm": None if z_mm is None else float(z_mm),
        }
        try:
            with self._write() as conn:
                capture_id = new_id(conn.execute(captures.insert().values(**values)))
        except RecordError:
            path.unlink(missing_ok=True)  # no row names it: an orphan would only mislead
            raise
        return CaptureRow(id=capture_id, **values)

    def captures(self, session_id: str, *, step_index: int | None = None) -> list[CaptureRow]:
        """The session's captures (of one step, if given), by step then frame."""
        query = sa.select(captures).where(captures.c.session_id == session_id)
        if step_index is not None:
            query = query.where(captures.c.step_index == step_index)
        query = query.order_by(captures.c.step_index, captures.c.frame_index)
        with self._read() as conn:
            return [capture_row(r) for r in conn.execute(query)]

    def latest_capture(self, session_id: str) -> CaptureRow | None:
        """The session's most recently stored capture (None before its first): one row, whatever the
        session holds (the live view asks for it with every measurement)."""
        query = (
            sa.select(captures)
            .where(captures.c.session_id == session_id)
            .order_by(captures.c.id.desc())
            .limit(1)
        )
        with self._read() as conn:
            r = conn.execute(query).first()
        return None if r is None else capture_row(r)

    def capture(self, capture_id: int) -> CaptureRow:
        """One capture by id."""
        with self._read() as conn:
            r = conn.execute(sa.select(captures).where(captures.c.id == capture_id)).first()
        if r is None:
            raise RecordError(f"no capture {capture_id} in the record at {self.url}")
        return capture_row(r)

    def load_image(self, capture: CaptureRow) -> npt.NDArray[np.uint8] | npt.NDArray[np.uint16]:
        """The capture's image, after checking the file's sha256 against the record."""
        return _images.read_checked(self.image_file(capture), capture.sha256)

    def image_file(self, capture: CaptureRow) -> Path:
        """The capture's image file (its recorded path checked to be the station's own for it)."""
        return capture_file(
            self._data_dir, capture.session_id, capture.step_index, capture.frame_index, capture.path
        )

    # -- measurements ----------------------------------------------------------------------------
    def add_measurement(
        self,
        session_id: str,
        capture_id: int,
        result: Mapping[str, Any],
        *,
        params: Mapping[str, Any],
        software: str,
    ) -> MeasurementRow:
        """Store one measurement (the ``station measure --json`` object, point arrays stripped)."""
        value: dict[str, Any] = strip_point_arrays(json_object(result, "result"))
        phash = params_hash(params)
        with self._write() as conn:
            self._require_session(conn, session_id)
            if conn.execute(sa.select(captures.c.id).where(captures.c.id == capture_id)).first() is None:
                raise RecordError(f"no capture {capture_id} in the record at {self.url} to measure")
            values: dict[str, Any] = {
                "session_id": session_id,
                "capture_id": capture_id,
                "params_hash": phash,
                "software": software,
                "ok": bool(value.get("ok", False)),
                "result": value,
            }
            mid = new_id(conn.execute(measurements.insert().values(**values)))
        return MeasurementRow(id=mid, **values)

    def latest_measurement(self, session_id: str, capture_id: int) -> MeasurementRow | None:
        """The session's most recent measurement of one capture (None before it is measured)."""
        query = (
            sa.select(measurements)
            .where(measurements.c.capture_id == capture_id, measurements.c.session_id == session_id)
            .order_by(measurements.c.id.desc())
            .limit(1)
        )
        with self._read() as conn:
            r = conn.execute(query).first()
        return None if r is None else measurement_row(r)

    def measurements(self, session_id: str) -> list[MeasurementRow]:
        """The session's measurements in the order they were stored."""
        query = sa.select(measurements).where(measurements.c.session_id == session_id)
        with self._read() as conn:
            return [measurement_row(r) for r in conn.execute(query.order_by(measurements.c.id))]
