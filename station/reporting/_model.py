"""The session mapping a report is drawn from, parsed and checked at the boundary (by the kinds'
results models, ``station.kinds``).

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
from collections.abc import Mapping
from typing import Any

from pydantic import ValidationError as PydanticValidationError

from station.kinds import KIND_NAMES, KINDS
from station.plans import PlanError
from station.plans._results import ResultsModel
from station.reporting._session import ReportError, Session


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


def _parse_results(kind: str, raw: Any) -> tuple[str | None, str | None, ResultsModel | None]:
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
