"""The ``selftest`` session kind: the controller self-test run as a session (``plan``), its typed results
(``results``) and how they are shown (``present``)."""

from station.kinds.selftest import present
from station.kinds.selftest.plan import SELFTEST
from station.kinds.selftest.results import SelftestResults
from station.plans._kind import Kind

KIND = Kind(
    plan=SELFTEST,
    results=SelftestResults,
    title="Controller self-test",
    summary=present.summary,
    rows=present.rows,
)

__all__ = ["KIND"]
