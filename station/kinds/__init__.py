"""The session kinds, one package each, and the one registry that the runner, the worker, the CLI, the API
and the report machinery ask (none of them names a kind).

A kind's package (``station/kinds/<kind>/``) holds its plan (parameter model, steps, resume rule, analysis
and gates) and exports ``KIND``, a :class:`~station.plans._kind.Kind`. Adding a kind is adding its folder
and one line below. Kinds import the plans' interfaces (``station.plans``), never the runner, the
worker, the record's internals or this registry.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from station.kinds import (
    calibration,
    camera_calibration,
    reanalyse,
    repeatability,
    selftest,
    sweep,
    validation,
)
from station.plans import Plan, PlanError
from station.plans._kind import Kind
from station.plans._present import checks_summary

KINDS: Mapping[str, Kind] = {
    k.name: k
    for k in (
        validation.KIND,
        repeatability.KIND,
        sweep.KIND,
        reanalyse.KIND,
        calibration.KIND,
        selftest.KIND,
        camera_calibration.KIND,
    )
}
KIND_NAMES: tuple[str, ...] = tuple(KINDS)


def get_kind(name: str) -> Kind:
    """The kind called ``name``; PlanError listing the kinds otherwise."""
    if name not in KINDS:
        raise PlanError(f"no plan named {name!r}; plans: {', '.join(sorted(KINDS))}")
    return KINDS[name]


def get_plan(name: str) -> Plan:
    """The plan of the kind called ``name``; PlanError listing the kinds otherwise."""
    return get_kind(name).plan


def _inner(kind: str, results: Mapping[str, Any]) -> tuple[str, Mapping[str, Any]] | None:
    """The kind and results that ``kind``'s results hold (a re-analysis's source's); ``None`` when its
    results are its own, or hold nothing readable."""
    entry = KINDS.get(kind)
    if entry is None or entry.inner is None:
        return None
    try:
        inner, body = entry.inner(results, KIND_NAMES)
    except PlanError:
        return "", {}
    return (inner, body) if isinstance(body, Mapping) else ("", {})


def summary(kind: str, results: Mapping[str, Any]) -> str:
    """A few lines for the terminal; ``station report`` writes the full tables and figures."""
    if not results:
        return "  no results"
    sources = results.get("sessions")
    if KINDS.get(kind) is not None and KINDS[kind].inner is not None and isinstance(sources, list):
        # a re-analysis of an archive selection: each source's, under its session
        return (
            "\n".join(
                f"  session {one.get('source_session')}:\n{summary(kind, one)}"
                for one in sources
                if isinstance(one, Mapping)
            )
            or "  no results"
        )
    inner = _inner(kind, results)
    if inner is not None:
        return summary(*inner)
    entry = KINDS.get(kind)
    text = (
        entry.summary(results)
        if entry is not None and entry.summary is not None
        else json.dumps(results)[:500]
    )
    return "\n".join(filter(None, [text, checks_summary(results)]))


def table_rows(kind: str, results: Mapping[str, Any]) -> list[dict[str, Any]]:
    """The rows of the results' CSV table (none for a kind without one); a re-analysis's are its
    source kind's."""
    inner = _inner(kind, results)
    if inner is not None:
        return table_rows(*inner) if inner[0] else []
    entry = KINDS.get(kind)
    return entry.rows(results) if entry is not None and entry.rows is not None else []


__all__ = ["KINDS", "KIND_NAMES", "Kind", "get_kind", "get_plan", "summary", "table_rows"]
