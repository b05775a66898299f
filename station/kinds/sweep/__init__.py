"""The ``sweep`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``: the terminal and the CSV; ``report``: the report's tables and
figures)."""

from station.kinds.sweep import present, report
from station.kinds.sweep.plan import SWEEP
from station.kinds.sweep.results import SweepResults
from station.plans._kind import Kind

KIND = Kind(
    plan=SWEEP,
    results=SweepResults,
    measure_defaults={"mode": "paper"},
    title="Parameter study",
    summary=present.summary,
    rows=present.rows,
    tables=report.tables,
    figures=report.figures,
)

__all__ = ["KIND"]
