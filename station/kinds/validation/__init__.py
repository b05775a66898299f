"""The ``validation`` session kind: its plan (``plan``), its typed results (``results``)
and how they are shown (``present``)."""

from station.kinds.validation import present
from station.kinds.validation.plan import VALIDATION
from station.kinds.validation.results import ValidationResults
from station.plans._kind import Kind

KIND = Kind(plan=VALIDATION, results=ValidationResults, summary=present.summary, rows=present.rows)

__all__ = ["KIND"]
