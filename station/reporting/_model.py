"""The session mapping a report is drawn from, parsed and checked at the boundary.

A session comes from the record (or its JSON export) as a plain mapping: ``id``, ``kind``, ``state``,
``created_at`` (ISO 8601), ``params``, ``identities``, ``software``, ``results`` (None until the session
has results) and, for a session that did not succeed, optionally ``error``. Results are parsed with
pydantic so that a malformed record is named precisely (``results.positions.3.measured_um``) instead of
failing somewhere inside matplotlib.

Units are in the key names: validation in um, repeatability in mm, sweep trials in um; calibration's
relative error in um, its residuals in mm, each parameter with its own ``unit`` (mm or deg).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from pydantic import ValidationError as PydanticValidationError

from station.kinds import KIND_NAMES, KINDS
from station.kinds.calibration.results import CalibrationResults
from station.kinds.repeatability.results import RepeatabilityResults
from station.kinds.sweep.results import SweepResults
from station.kinds.validation.results import ValidationResults
from station.plans import PlanError
from station.plans._results import Check


class ReportError(ValueError):
    """A session cannot be reported: not a session mapping, or its results are malformed."""


Results = ValidationResults | RepeatabilityResults | SweepResults | CalibrationResults


@dataclass(frozen=True)
class Session:
    """A session's facts for the report header, and its results parsed (None when there are none).

    ``results_kind``: the kind the results are drawn as (a re-analysis is drawn as its source's kind);
    ``problem``: why the results could not be parsed (only for sessions that did not succeed, whose
    results may be partial; ``raw_results`` then keeps them for the report to show as they are).
    """

    id: str
    kind: str
    state: str
    created_at: str
    params: Mapping[str, Any]
    identities: Mapping[str, Any]
    software: Mapping[str, Any]
    error: str | None
    source_session: str | None
    results_kind: str | None
    results: Results | None
    raw_results: Any
    problem: str | None

    @property
    def succeeded(self) -> bool:
        return self.state == "succeeded"

    @property
    def failed_checks(self) -> list[Check]:
        """The ``fail`` checks its results did not pass (why a session with results failed)."""
        checks: list[Check] = getattr(self.results, "checks", [])
        return [c for c in checks if c.severity == "fail" and not c.passed]


def _error_text(error: Any) -> str | None:
    if error is None or error == "":
        return None
    if isinstance(error, Mapping):
        message = error.get("message") or error.get("error")
        code = error.get("code")
        if message is not None:
            return f"{message} ({code})" if code else str(message)
        return json.dumps(error, default=str)
    return str(error)


def _describe(exc: PydanticValidationError) -> str:
    first = exc.errors(include_url=False)[0]
    where = ".".join(str(p) for p in ("results", *first["loc"]))
    more = f" (and {exc.error_count() - 1} more)" if exc.error_count() > 1 else ""
    return f"{where}: {first['msg']}{more}"


def _parse_results(kind: str, raw: Any) -> tuple[str | None, str | None, Results | None]:
    """(kind drawn, source session, parsed results) of a session's ``results``: results that hold
    another kind's (a re-analysis) are drawn as that kind's."""
    if raw is None:
        return None, None, None
    if not isinstance(raw, Mapping):
        raise ReportError(f"results must be an object, got {type(raw).__name__}")
    source = raw.get("source_session")
    source_id = None if source is None else str(source)
    entry = KINDS[kind]
    if entry.inner is not None:
        try:
            inner, inner_raw = entry.inner(raw, KIND_NAMES)
        except PlanError as exc:
            raise ReportError(str(exc)) from None
        drawn, inner_source, results = _parse_results(inner, inner_raw)
        return drawn, source_id if source_id is not None else inner_source, results
    try:
        parsed = entry.results.model_validate(raw)
    except PydanticValidationError as exc:
        raise ReportError(_describe(exc)) from None
    assert isinstance(parsed, ValidationResults | RepeatabilityResults | SweepResults | CalibrationResults)
    return kind, source_id, parsed


def parse_session(session: Mapping[str, Any]) -> Session:
    """Check a session mapping and parse its results (ReportError naming the field when malformed)."""
    if not isinstance(session, Mapping):
        raise ReportError(f"a session must be a mapping, got {type(session).__name__}")
    missing = [k for k in ("id", "kind", "state") if session.get(k) is None]
    if missing:
        raise ReportError(f"the session lacks {', '.join(map(repr, missing))}: is this a session record?")
    sid, kind, state = str(session["id"]), str(session["kind"]), str(session["state"])
    if kind not in KINDS:
        raise ReportError(f"session {sid}: unknown kind {kind!r}; known: {', '.join(KIND_NAMES)}")
    raw = session.get("results")
    problem = None
    try:
        results_kind, source, results = _parse_results(kind, raw)
    except ReportError as exc:
        if state == "succeeded":
            raise ReportError(f"session {sid} ({kind}, succeeded) has malformed results: {exc}") from None
        results_kind, source, results, problem = None, None, None, str(exc)
        if isinstance(raw, Mapping) and raw.get("source_session") is not None:
            source = str(raw["source_session"])
    return Session(
        id=sid,
        kind=kind,
        state=state,
        created_at=str(session.get("created_at") or ""),
        params=_mapping(session.get("params")),
        identities=_mapping(session.get("identities")),
        software=_mapping(session.get("software")),
        error=_error_text(session.get("error")),
        source_session=source,
        results_kind=results_kind,
        results=results,
        raw_results=raw,
        problem=problem,
    )


def _mapping(value: Any) -> Mapping[str, Any]:
    return value if isinstance(value, Mapping) else {}


def format_date(iso: str) -> str:
    """An ISO 8601 time as ``YYYY-MM-DD HH:MM:SS UTC`` (or with its offset); unparsable text as given."""
    try:
        when = datetime.fromisoformat(iso)
    except ValueError:
        return iso
    if when.tzinfo is None:
        return when.strftime("%Y-%m-%d %H:%M:%S")
    if when.utcoffset() == UTC.utcoffset(None):
        return when.strftime("%Y-%m-%d %H:%M:%S UTC")
    return when.strftime("%Y-%m-%d %H:%M:%S %z")


def format_value(value: Any) -> str:
    """A parameter or identity value as compact text (JSON for structures, "-" for none)."""
    if value is None:
        return "-"
    if isinstance(value, str):
        return value
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    try:
        return json.dumps(value, default=str, allow_nan=True)
    except (TypeError, ValueError):
        return str(value)
