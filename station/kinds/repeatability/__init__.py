"""The ``repeatability`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``)."""

from station.kinds.repeatability import present
from station.kinds.repeatability.plan import REPEATABILITY
from station.kinds.repeatability.results import RepeatabilityResults
from station.plans._kind import Kind

KIND = Kind(plan=REPEATABILITY, results=RepeatabilityResults, summary=present.summary, rows=present.rows)

__all__ = ["KIND"]
