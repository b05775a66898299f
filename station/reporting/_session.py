"""What a report is drawn from: a session's facts and its results parsed by its kind's results model
(``parse_session`` in ``_model.py`` makes it), and how values are written in the report.

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

from station.plans._results import Check, ResultsModel


class ReportError(ValueError):
    """A session cannot be reported: not a session mapping, or its results are malformed."""


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
    results: ResultsModel | None
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
