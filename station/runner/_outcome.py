"""A session's outcome: the plan's analysis of what was stored, and what a passed validation leaves (the
station's scale calibration)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from station import scale_calibration
from station.plans import Plan, PlanContext, PlanError
from station.plans._recorded import stored_captures
from station.record import Record, RecordError
from station.runner._journal import Journal
from station.runner._states import SessionState


@dataclass(frozen=True)
class Analysis:
    """The plan's results (``None`` when there are none) and, when that fails a whole session, why."""

    results: dict[str, Any] | None
    error: str | None = None


def analyse(
    plan: Plan, params: BaseModel, ctx: PlanContext, record: Record, journal: Journal, *, keep_going: bool
) -> Analysis:
    """The plan's analysis of the session's stored captures (those of its source session for a plan that
    re-analyses one). ``keep_going``: the session already ended otherwise; a failed analysis is then
    only a warning (no results from a partial session), else the session's error."""
    assert ctx.session_id is not None
    try:
        return Analysis(plan.analyse(params, ctx, captures_of(plan, params, record, ctx.session_id)))
    except (PlanError, ValueError, RecordError) as exc:
        if keep_going:
            journal.emit("warning", {"message": f"no results from the partial session: {exc}"})
            return Analysis(None)
        error = f"analysis failed: {exc}"
        journal.emit("error", {"message": error})
        return Analysis(None, error)


def captures_of(plan: Plan, params: BaseModel, record: Record, sid: str) -> list[Any]:
    """What the plan's analysis (and its live gates) read: the stored captures with this session's
    measurements (of the source session's captures, for a re-analysis)."""
    source_of = getattr(plan, "source_session", None)
    named = source_of(params) if source_of is not None else None  # None: an archive selection
    source = record.get_session(named).id if named is not None else sid
    return stored_captures(record, source, measured_in=sid)


def write_scale_calibration(plan: Plan, record: Record, results: Any, journal: Journal) -> None:
    """A validation that passed every gate: its groove-width estimate becomes the station's scale
    calibration (the one it replaces stays in the history, ``station.scale_calibration``)."""
    cal = scale_calibration.from_validation(plan.name, SessionState.SUCCEEDED, results)
    if cal is None:
        return
    try:
        entry = scale_calibration.write(record.data_dir, cal)
    except (scale_calibration.ScaleCalibrationError, OSError) as exc:
        journal.emit("warning", {"message": f"the scale calibration could not be written: {exc}"})
        return
    journal.emit("scale_calibration", {"version": entry.version, **cal.record()})
