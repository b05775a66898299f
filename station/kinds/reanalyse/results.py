"""The ``reanalyse`` kind's results: the source session's kind and its results measured again, held under
that kind's name (``{"source_session", "kind": "validation", "validation": {...}, "checks"}``); over an
archive selection, one such object per source under ``sessions`` and their checks, each named after its
session (``{"sessions": [...], "checks"}``)."""

from __future__ import annotations

from collections.abc import Collection, Mapping
from typing import Any

from pydantic import ConfigDict, Field

from station.plans import PlanError
from station.plans._results import Check, ResultsModel


class ReanalyseResults(ResultsModel):
    """A re-analysis: the source's kind, and the source kind's results under that kind's name (typed by
    that kind's results model)."""

    model_config = ConfigDict(extra="allow", frozen=True)

    source_session: str | None = None
    kind: str | None = Field(None, description="the source session's kind: its results are under this name")
    checks: list[Check] = Field(default_factory=list)
    sessions: list[ReanalyseResults] | None = Field(
        None, description="an archive selection: each source's re-analysis, in the selection's order"
    )


def inner_results(raw: Mapping[str, Any], kinds: Collection[str]) -> tuple[str, Any]:
    """(the source's kind, its results) of a re-analysis's results; PlanError when they name neither."""
    named = raw.get("kind")
    if named is None and isinstance(raw.get("sessions"), list):
        raise PlanError(
            f"a re-analysis of {len(raw['sessions'])} sessions holds each source's results under "
            "'sessions' (see them with: station sessions --json)"
        )
    if named is None:
        found = [k for k in kinds if raw.get(k) is not None]
        named = found[0] if len(found) == 1 else None
    inner = str(named)
    if named not in kinds or raw.get(inner) is None:
        raise PlanError(
            "results of a reanalyse session must name the source's kind ('kind') and hold its results "
            f"under that name, one of {', '.join(map(repr, kinds))}"
        )
    return inner, raw[inner]
