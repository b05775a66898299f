"""The record's rows as frozen dataclasses: what readers of the record get back."""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime
from typing import Any, Literal, get_args

import sqlalchemy as sa

StepState = Literal["started", "done", "failed"]
STEP_STATES: tuple[str, ...] = get_args(StepState)
SessionState = Literal[
    "idle", "running", "pausing", "paused", "awaiting_operator", "stopping", "stopped", "aborting",
    "aborted", "failed", "succeeded", "interrupted",
]  # fmt: skip
SESSION_STATES: tuple[str, ...] = get_args(SessionState)
"""The runner's state names (``station.runner.SessionState``), which the record cannot import."""


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


# ------------------------------------------------------------------ from the database's rows


def session_row(r: sa.Row[Any]) -> SessionRow:
    return SessionRow(
        id=r.id,
        kind=r.kind,
        state=r.state,
        created_at=r.created_at,
        updated_at=r.updated_at,
        params=r.params,
        config=r.config,
        identities=r.identities,
        software=r.software,
        results=r.results,
        error=r.error,
        parent_id=r.parent_id,
        station=r.station,
    )


def event_row(r: sa.Row[Any]) -> EventRow:
    return EventRow(id=r.id, session_id=r.session_id, seq=r.seq, time=r.time, type=r.type, data=r.data)


def step_row(r: sa.Row[Any]) -> StepRow:
    return StepRow(
        session_id=r.session_id,
        index=r.step_index,
        name=r.name,
        state=r.state,
        data=r.data,
        started_at=r.started_at,
        finished_at=r.finished_at,
    )


def capture_row(r: sa.Row[Any]) -> CaptureRow:
    return CaptureRow(
        id=r.id,
        session_id=r.session_id,
        step_index=r.step_index,
        frame_index=r.frame_index,
        path=r.path,
        width=r.width,
        height=r.height,
        dtype=r.dtype,
        sha256=r.sha256,
        timestamp_s=r.timestamp_s,
        meta=r.meta,
        z_mm=r.z_mm,
    )


def measurement_row(r: sa.Row[Any]) -> MeasurementRow:
    return MeasurementRow(
        id=r.id,
        session_id=r.session_id,
        capture_id=r.capture_id,
        params_hash=r.params_hash,
        software=r.software,
        ok=r.ok,
        result=r.result,
    )
