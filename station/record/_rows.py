"""The record's rows as frozen dataclasses: what readers of the record get back."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any

STEP_STATES = ("started", "done", "failed")


@dataclass(frozen=True)
class SessionRow:
    """One session: what was run, with which parameters, devices and software, and how it ended."""

    id: str
    kind: str
    state: str
    created_at: datetime
    updated_at: datetime
    params: dict[str, Any]
    config: dict[str, Any]
    identities: dict[str, Any]
    software: dict[str, Any]
    results: dict[str, Any] | None
    error: str | None
    parent_id: str | None
    station: str


@dataclass(frozen=True)
class EventRow:
    """One event: ``id`` increases station-wide (the database's), ``seq`` per session from 1."""

    id: int
    session_id: str
    seq: int
    time: datetime
    type: str
    data: dict[str, Any]


@dataclass(frozen=True)
class StepRow:
    """One step of a session's plan; ``state`` is ``started``, ``done`` or ``failed``."""

    session_id: str
    index: int
    name: str
    state: str
    data: dict[str, Any]
    started_at: datetime
    finished_at: datetime | None


@dataclass(frozen=True)
class CaptureRow:
    """One stored frame; ``path`` is relative to the data directory, ``sha256`` of the file bytes.

    ``z_mm``: the distance sensor's reading taken with the frame (mm), ``None`` without a sensor or
    without a valid reading (the capture's ``meta["z_error"]`` then says why)."""

    id: int
    session_id: str
    step_index: int
    frame_index: int
    path: str
    width: int
    height: int
    dtype: str
    sha256: str
    timestamp_s: float
    meta: dict[str, Any]
    z_mm: float | None = None


@dataclass(frozen=True)
class MeasurementRow:
    """One measurement of a capture: the ``station measure --json`` object, without edge points."""

    id: int
    session_id: str
    capture_id: int
    params_hash: str
    software: str
    ok: bool
    result: dict[str, Any]
