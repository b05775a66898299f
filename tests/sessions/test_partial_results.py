"""Partial results are visible (issue 19, finding 4 and item 5): a repeatability session aborted in its
first test reports that test with its own N and RP, marked partial and kept out of the headline
``rp_mm``; the tests it never reached say so with N = 0; the report and the terminal show the same."""

from __future__ import annotations

from pathlib import Path

from station.kinds import get_plan, summary
from station.plans import parse_params
from station.record import Record
from station.reporting import text_tables, write_report
from station.resources import report_document
from station.runner import SessionRunner, SessionState
from station.testing import FakeStation
from tests.sessions.conftest import results_of, sid_of


def aborted_repeatability(record: Record) -> SessionRunner:
    plan = get_plan("repeatability")
    params = parse_params(plan, {"cycles": 8, "warmup_cycles": 0, "joints": [1, 2, 3], "settle_s": 0.0})
    runner = SessionRunner(record, plan, params, devices=FakeStation().devices())
    # J1: step 0 its reference, 1-8 its cycles; aborted as its sixth cycle starts: five measured
    runner.subscribe(lambda e: runner.abort() if e.type == "step_started" and e.data["index"] == 6 else None)
    assert runner.run() is SessionState.ABORTED
    return runner


def test_an_aborted_repeatability_reports_each_test_with_its_n_and_partial(record: Record) -> None:
    runner = aborted_repeatability(record)
    res = results_of(record, runner)
    j1 = res["tests"]["J1"]
    assert (j1["n_cycles"], j1["planned_cycles"], j1["partial"]) == (5, 8, True)
    assert len(j1["points_mm"]) == 5
    assert "rp_mm" in j1  # its own RP, from its 5 cycles
    assert res["rp_mm"] == {}  # never in the headline
    for test in ("J2", "J3"):  # never reached: an error with N = 0, not silence
        assert res["tests"][test]["n_cycles"] == 0
        assert res["tests"][test]["partial"] is True
        assert "RP needs at least 3" in res["tests"][test]["error"]
    assert res["partial"] is True
    cycles = {c["name"]: c for c in res["checks"] if c["name"].startswith("cycles:")}
    assert cycles["cycles:J1"]["passed"] is False
    assert cycles["cycles:J1"]["severity"] == "warn"
    assert (cycles["cycles:J1"]["value"], cycles["cycles:J1"]["limit"]) == (5, 8)


def test_the_report_and_the_terminal_show_partial_and_n(record: Record, tmp_path: Path) -> None:
    runner = aborted_repeatability(record)
    row = record.get_session(sid_of(runner))
    table = text_tables(report_document(row))["repeatability"]
    j1 = next(line for line in table.splitlines() if line.strip().startswith("J1"))
    assert "5 of 8 (partial)" in j1
    j2 = next(line for line in table.splitlines() if line.strip().startswith("J2"))
    assert "no RP" in j2
    assert "0 of 8 (partial)" in j2
    assert "8 cycles planned per test" in table
    assert "not in the headline" in table
    checks = text_tables(report_document(row))["checks"]
    assert "J1 is partial: 5 of 8 cycles measured" in checks
    page = write_report(report_document(row), tmp_path / "report").html.read_text()
    assert "5 of 8 (partial)" in page
    text = summary("repeatability", row.results or {})
    assert "J1  RP" in text
    assert "N 5 of 8, partial" in text
    assert "N 0 of 8, partial" in text
