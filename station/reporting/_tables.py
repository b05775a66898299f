"""The report's tables: every session's (facts, devices, parameters, checks), then those of the kind its
results are drawn as (``station.kinds``: each kind's report module)."""

from __future__ import annotations

from station.kinds import KINDS
from station.plans._results import Check
from station.reporting._model import Session
from station.reporting._table import Table, checks_table, devices_table, parameters_table, session_table


def results_tables(s: Session) -> dict[str, Table]:
    """The tables of a session's results (none when it has none), their checks first."""
    checks: list[Check] = getattr(s.results, "checks", [])
    tables = _kind_tables(s)
    return {"checks": checks_table(checks), **tables} if checks else tables


def _kind_tables(s: Session) -> dict[str, Table]:
    if s.results is None or s.results_kind is None:
        return {}
    tables = KINDS[s.results_kind].tables
    return dict(tables(s.results, s)) if tables is not None else {}


def all_tables(s: Session) -> dict[str, Table]:
    """Session facts, devices, parameters, then the results' tables."""
    return {
        "session": session_table(s),
        "devices": devices_table(s),
        "parameters": parameters_table(s),
        **results_tables(s),
    }
