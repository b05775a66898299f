"""The ``reanalyse`` session kind: its plan (``plan``), its typed results (``results``), which hold
the source kind's (``inner_results``)."""

from station.kinds.reanalyse.plan import REANALYSE
from station.kinds.reanalyse.results import ReanalyseResults, inner_results
from station.plans._kind import Kind

KIND = Kind(
    plan=REANALYSE,
    results=ReanalyseResults,
    remeasures_source=True,
    title="Re-analysis",
    inner=inner_results,
)

__all__ = ["KIND"]
