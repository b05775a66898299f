"""The ``calibration`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``)."""

from station.kinds.calibration import present
from station.kinds.calibration.plan import CALIBRATION
from station.kinds.calibration.results import CalibrationResults
from station.plans._kind import Kind

KIND = Kind(plan=CALIBRATION, results=CalibrationResults, summary=present.summary, rows=present.rows)

__all__ = ["KIND"]
