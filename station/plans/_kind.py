"""A session kind as the registry (``station.kinds``) holds it: its plan, its typed results model, how its
results are shown and, optionally, how its results hold another kind's (a re-analysis)."""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from station.plans import Plan
from station.plans._results import ResultsModel

#: (the inner kind, its results) of results that hold another kind's (``reanalyse``)
InnerResults = Callable[[Mapping[str, Any], Collection[str]], tuple[str, Any]]
#: a few lines for the terminal (``station run``, ``station calibrate``)
Summary = Callable[[Mapping[str, Any]], str]
#: the rows of the results' CSV table (``GET /api/v1/sessions/{id}/results?format=csv``)
Rows = Callable[[Mapping[str, Any]], list[dict[str, Any]]]
#: the report's tables of the parsed results (results, the report's session), by name
Tables = Callable[[Any, Any], Mapping[str, Any]]
#: the report's figures of the parsed results
Figures = Callable[[Any], Sequence[Any]]


@dataclass(frozen=True)
class Kind:
    """One session kind.

    ``plan``: its parameter model, steps, resume rule and analysis with its gates. ``results``: the typed
    model of what its analysis returns (published in the API's OpenAPI document, parsed by the report).
    ``title``: the report's heading. ``measure_defaults``: its measurement parameters' defaults (under
    the configuration's and ``--set``). ``scale_calibrated``: the station's scale calibration gives its
    groove width (unless ``--set`` does). ``remeasures_source``: it measures a stored session again,
    with that session's measurement parameters and scale calibration (unless ``--set`` changes them).
    ``summary`` and ``rows``: the terminal's lines and the CSV table's rows of its results (none: the
    results shown as JSON, no table). ``tables`` and ``figures``: the report's (``station.reporting``
    draws them with its machinery). ``inner``: for a kind whose results hold another kind's (a
    re-analysis), where they are; they are shown and drawn as that kind's.
    """

    plan: Plan
    results: type[ResultsModel]
    title: str = ""
    measure_defaults: Mapping[str, Any] = field(default_factory=dict)
    scale_calibrated: bool = False
    remeasures_source: bool = False
    summary: Summary | None = None
    rows: Rows | None = None
    tables: Tables | None = None
    figures: Figures | None = None
    inner: InnerResults | None = None

    @property
    def name(self) -> str:
        return self.plan.name
