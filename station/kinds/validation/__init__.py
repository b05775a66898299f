"""The ``validation`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``: the terminal and the CSV; ``report``: the report's tables and
figures)."""

from station.kinds.validation import present, report
from station.kinds.validation.plan import VALIDATION
from station.kinds.validation.results import ValidationResults
from station.plans._kind import Kind

KIND = Kind(
    plan=VALIDATION,
    results=ValidationResults,
    scale_calibrated=True,
    title="Validation against the X-Y table",
    summary=present.summary,
    rows=present.rows,
    tables=report.tables,
    figures=report.figures,
)

__all__ = ["KIND"]
