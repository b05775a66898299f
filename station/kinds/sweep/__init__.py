"""The ``sweep`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``)."""

from station.kinds.sweep import present
from station.kinds.sweep.plan import SWEEP
from station.kinds.sweep.results import SweepResults
from station.plans._kind import Kind

KIND = Kind(plan=SWEEP, results=SweepResults, summary=present.summary, rows=present.rows)

__all__ = ["KIND"]
