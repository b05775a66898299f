"""The ``repeatability`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``: the terminal and the CSV; ``report``: the report's tables and
figures)."""

from station.kinds.repeatability import present, report
from station.kinds.repeatability.plan import REPEATABILITY
from station.kinds.repeatability.results import RepeatabilityResults
from station.plans._kind import Kind

KIND = Kind(
    plan=REPEATABILITY,
    results=RepeatabilityResults,
    scale_calibrated=True,
    title="Pose repeatability",
    summary=present.summary,
    rows=present.rows,
    tables=report.tables,
    figures=report.figures,
)

__all__ = ["KIND"]
