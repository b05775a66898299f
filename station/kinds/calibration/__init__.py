"""The ``calibration`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``: the terminal and the CSV; ``report``: the report's tables and
figures)."""

from station.kinds.calibration import present, report_figures, report_tables
from station.kinds.calibration.plan import CALIBRATION
from station.kinds.calibration.results import CalibrationResults
from station.plans._kind import Kind

KIND = Kind(
    plan=CALIBRATION,
    results=CalibrationResults,
    title="Kinematic calibration",
    summary=present.summary,
    rows=present.rows,
    tables=report_tables.tables,
    figures=report_figures.figures,
)

__all__ = ["KIND"]
