"""Issue 19's page side: what the page shows so that no wrong number passes for a right one, and the arm is
always recoverable. The gates of a session that failed them (``results.checks``, the failed rows marked),
partial repeatability tests (N of the planned cycles, never in the headline RP), "Move to the reference
pose" after an aborted calibration (the route's moves from ``GET /station/robot``, confirmed, then gone
once the arm is back), and the station's scale calibration (its width, its session, its history) with a
confirmed revert.

The tests share one simulated station (a module's service): each starts from the arm at its reference
pose and leaves it there.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from api import Access, ServiceSettings, StationService
from tests.api.conftest import TOKEN, Served, acknowledge_stop, serve, wait_final, wait_state
from tests.api.page.conftest import PATTERN, api, open_page
from tests.api.test_to_reference import CALIBRATION, seen_artifact, wait_over_the_first_artifact


@pytest.fixture(scope="module")
def station(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    data: Path = tmp_path_factory.mktemp("trust") / "data"
    served = serve(StationService(ServiceSettings(sim=True, data=data)), Access(TOKEN, True))
    try:
        yield served
    finally:
        served.stop()


def run(c: httpx.Client, kind: str, params: dict[str, Any]) -> dict[str, Any]:
    r = c.post("/api/v1/sessions", json={"kind": kind, "params": params})
    assert r.status_code == 201, r.text
    return wait_final(c, r.json()["id"])


def rows_of(page: Any, table: str) -> list[list[str]]:
    return list(
        page.eval_on_selector_all(
            f"{table} tbody tr", "rows => rows.map(r => [...r.cells].map(c => c.textContent))"
        )
    )


def shown_as(v: float, digits: int) -> str:
    """A number as the page writes it: an integer as one, others with ``digits`` decimals."""
    return str(int(v)) if float(v).is_integer() else f"{v:.{digits}f}"


SHOWN = "sid => document.querySelector('#session-id').textContent === sid"


def pairs(page: Any, table: str) -> dict[str, str]:
    """A key-value table's rows (label, value)."""
    found = page.eval_on_selector_all(
        f"{table} tr", "rs => rs.map(r => [r.cells[0].textContent, r.cells[1].textContent])"
    )
    return {str(k): str(v) for k, v in found}


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_a_validation_that_failed_its_gates_shows_every_check_with_the_failed_ones_marked(
    station: Served, browser: Any
) -> None:
    with api(station.base) as c:
        # limits no real table meets (0.01 um): the rigid fit's gates fail, everything else passes
        final = run(c, "validation", {"pattern_um": PATTERN, "mean_limit_um": 0.01, "max_limit_um": 0.02})
    assert final["state"] == "failed"
    checks = {ch["name"]: ch for ch in final["results"]["checks"]}
    failed = [n for n, ch in checks.items() if not ch["passed"] and ch["severity"] == "fail"]
    assert sorted(failed) == ["rigid_max", "rigid_mean"]

    visit = open_page(browser, station.base)
    page = visit.page
    page.wait_for_function(
        "sid => document.querySelector('#session-id').textContent === sid", arg=final["id"]
    )
    page.wait_for_selector("#checks-table")
    rows = page.eval_on_selector_all(
        "#checks-table tbody tr",
        "rs => rs.map(r => [r.dataset.check, r.dataset.verdict, r.cells[1].textContent])",
    )
    # every check is shown, the failed ones first and marked
    assert sorted(name for name, _, _ in rows) == sorted(checks)
    assert [(name, verdict, text) for name, verdict, text in rows[:2]] == [
        ("rigid_mean", "fail", "FAILED"),
        ("rigid_max", "fail", "FAILED"),
    ]
    # and the warning that no controller self-test is on record (station.selftest_status): not a failure
    assert [verdict for name, verdict, _ in rows if name == "selftest"] == ["warn"]
    assert all(verdict == "passed" for name, verdict, _ in rows[2:] if name != "selftest")
    caption = page.text_content("#checks-table caption") or ""
    assert "2 failed" in caption
    # a band's limit reads as one: low – high (mm)
    low, high = checks["groove_width"]["limit"]
    groove = next(r for r in rows_of(page, "#checks-table") if r[0] == "groove_width")
    assert groove[3] == f"{low:.5f} – {high:.5f}"
    assert groove[4] == checks["groove_width"]["message"]
    # why the session failed, and that what it measured is kept but not used
    status = page.text_content("#results-state") or ""
    assert status.startswith(f"Session {final['id']} failed: the results failed their checks")
    assert "Its results failed 2 checks (rigid_mean, rigid_max, marked below)" in status
    assert "the station's scale calibration was not written" in status
    assert page.get_attribute("#results-state", "data-gates") == "failed"
    # the values stay on show: the mean error is the one the gate refused
    table = pairs(page, "#results-table")
    assert table["mean error (after the rigid fit)"] == f"{final['results']['mean_um']:.3f} µm"
    assert visit.failed == []
    assert visit.console_errors == []


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_partial_repeatability_tests_show_n_of_the_planned_cycles_and_stay_out_of_the_headline(
    station: Served, browser: Any
) -> None:
    cycles = 6
    params = {"cycles": cycles, "joints": [1, 2, 3], "warmup_cycles": 0}
    with api(station.base) as c:
        r = c.post("/api/v1/sessions", json={"kind": "repeatability", "params": params})
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        # paused inside J2 (after its third cycle at the earliest, before its last), then aborted: J1 whole,
        # J2 partial with an RP of its own, J3 never started
        while not any(s.name == "J2 cycle 3" for s in station.service.record.steps(sid)):
            time.sleep(0.02)
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "pause"}).status_code == 201
        wait_state(c, sid, {"paused"})
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        final = wait_final(c, sid)
        acknowledge_stop(c)  # the abort latched the robot's stop; the next tests move the arm
    assert final["state"] == "aborted"
    results = final["results"]
    tests = results["tests"]
    assert list(results["rp_mm"]) == ["J1"]
    assert 3 <= tests["J2"]["n_cycles"] < cycles
    assert tests["J2"]["partial"] is True
    assert tests["J3"]["n_cycles"] == 0
    assert "error" in tests["J3"]

    visit = open_page(browser, station.base)
    page = visit.page
    page.wait_for_function(SHOWN, arg=sid)
    page.wait_for_selector("#tests-table")
    rows = {row[0]: row for row in rows_of(page, "#tests-table")}
    partial = page.eval_on_selector_all("#tests-table tbody tr", "rs => rs.map(r => r.dataset.partial)")
    assert partial == ["false", "true", "true"]
    # N per test: of the planned cycles when partial
    assert rows["J1"][2] == str(cycles)
    assert rows["J2"][2] == f"{tests['J2']['n_cycles']} of {cycles} (partial)"
    assert rows["J3"][2] == f"0 of {cycles} (partial)"
    # RP: the whole test's in the headline; the partial one's its own, marked; none without 3 cycles
    assert rows["J1"][3] == f"{tests['J1']['rp_mm']:.5f}"
    assert rows["J2"][3] == f"{tests['J2']['rp_mm']:.5f} (partial: not in RP)"
    assert rows["J3"][3] == f"not computed: {tests['J3']['error']}"
    summary = pairs(page, "#results-table")
    assert summary["RP (whole tests only)"] == f"J1 {results['rp_mm']['J1']:.5f} mm"
    assert summary["partial tests (their own RP, not in the headline)"] == (
        f"J2: N {tests['J2']['n_cycles']} of {cycles} (partial); J3: N 0 of {cycles} (partial)"
    )
    assert visit.failed == []
    assert visit.console_errors == []


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_after_an_aborted_calibration_the_page_offers_the_route_to_the_reference_pose(
    station: Served, browser: Any
) -> None:
    visit = open_page(browser, station.base)
    page = visit.page
    page.wait_for_function("document.querySelector('#robot-section').dataset.atReference === 'true'")
    assert page.is_hidden("#to-reference")
    with api(station.base) as c:
        r = c.post("/api/v1/sessions", json=CALIBRATION)
        assert r.status_code == 201, r.text
        sid = r.json()["id"]
        wait_over_the_first_artifact(station, sid)
        assert c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).status_code == 201
        assert wait_final(c, sid)["state"] == "aborted"
        arm = c.get("/api/v1/station/robot").json()
    assert arm["at_reference"] is False
    moves = arm["route"]["moves"]
    assert arm["route"]["via_lift"] is True
    assert arm["route"]["problems"] == []

    # the abort latched the robot's stop: no route is offered until the operator acknowledges it
    page.wait_for_selector("#latch", state="visible")
    assert page.is_hidden("#to-reference")
    page.wait_for_function("!document.querySelector('#acknowledge').disabled")
    page.click("#acknowledge")
    page.wait_for_selector("#latch", state="hidden")

    # offered as soon as the page reads the arm off its reference pose
    page.wait_for_selector("#to-reference", state="visible")
    assert "not at the reference pose" in (page.text_content("#robot-state") or "")
    page.click("#to-reference")
    page.wait_for_function("document.querySelector('#to-reference-route').dataset.route === 'ok'")
    route = page.text_content("#to-reference-route") or ""
    assert f"{len(moves)} moves, up through the lift pose" in route
    shown = page.eval_on_selector_all("#to-reference-moves li", "ls => ls.map(l => l.textContent)")
    assert shown == [", ".join(shown_as(a, 3) for a in q) + "°" for q in moves]
    assert page.is_enabled("#to-reference-yes")
    assert station.service.in_worker(seen_artifact) == 1  # nothing moved before the confirmation

    page.click("#to-reference-yes")
    page.wait_for_selector("#to-reference", state="hidden")
    page.wait_for_function("document.querySelector('#robot-section').dataset.atReference === 'true'")
    message = page.text_content("#robot-message") or ""
    assert re.fullmatch(rf"at the reference pose after {len(moves)} moves: joints .*°", message), message
    assert "at the reference pose" in (page.text_content("#robot-state") or "")
    with api(station.base) as c:
        assert c.get("/api/v1/station/robot").json()["at_reference"] is True
    assert station.service.in_worker(seen_artifact) == 0  # the camera over the table's artifact again
    assert visit.failed == []
    assert visit.console_errors == []


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_the_scale_calibration_is_shown_with_its_history_and_reverted_after_a_confirmation(
    station: Served, browser: Any
) -> None:
    with api(station.base) as c:
        first = run(c, "validation", {"pattern_um": PATTERN})
        second = run(c, "validation", {"pattern_um": PATTERN})
        assert first["state"] == second["state"] == "succeeded"
        now = c.get("/api/v1/station/scale-calibration").json()
        history = c.get("/api/v1/station/scale-calibration/history").json()["items"]
    current = now["calibration"]
    assert current["session_id"] == second["id"]
    earlier = next(e for e in history if e["version"] == history[0]["previous"])
    assert earlier["calibration"]["session_id"] == first["id"]

    visit = open_page(browser, station.base)
    page = visit.page
    page.wait_for_function(
        "v => document.querySelector('#scale-current').dataset.version === v", arg=str(current["version"])
    )
    text = page.text_content("#scale-current") or ""
    assert page.text_content("#scale-width") == f"groove width {current['groove_width_mm']:.5f} mm"
    assert f"version {current['version']}, from validation session {second['id']}" in text
    passed = sum(1 for ch in current["checks"] if ch["passed"])
    assert f"it passed {passed} of its {len(current['checks'])} checks" in text
    rows = rows_of(page, "#scale-history")
    assert [r[0] for r in rows] == [str(e["version"]) for e in history]  # newest first, every change
    assert rows[0][2:] == ["validation", f"{current['groove_width_mm']:.5f} mm", second["id"]]
    assert page.get_attribute("#scale-history tbody tr.selected", "data-version") == str(current["version"])

    # Revert asks first, saying what the station will measure with
    assert page.text_content("#scale-revert") == f"Revert to version {earlier['version']}…"
    page.click("#scale-revert")
    ask = page.text_content("#scale-revert-text") or ""
    width = earlier["calibration"]["groove_width_mm"]
    assert (
        f"Back to version {earlier['version']}: groove width {width:.5f} mm, from session {first['id']}"
        in ask
    )
    page.click("#scale-revert-no")  # not yet: nothing changes
    assert page.is_hidden("#scale-revert-confirm")
    with api(station.base) as c:
        assert c.get("/api/v1/station/scale-calibration").json()["calibration"]["session_id"] == second["id"]
    page.click("#scale-revert")
    page.click("#scale-revert-yes")
    page.wait_for_function(
        "n => document.querySelectorAll('#scale-history tbody tr').length === n", arg=len(history) + 1
    )
    assert (page.text_content("#scale-message") or "").startswith("reverted: version")
    assert f"from validation session {first['id']}" in (page.text_content("#scale-current") or "")
    newest = rows_of(page, "#scale-history")[0]
    assert newest[2:] == [f"revert to version {earlier['version']}", f"{width:.5f} mm", first["id"]]
    with api(station.base) as c:
        back = c.get("/api/v1/station/scale-calibration").json()["calibration"]
    assert (back["session_id"], back["groove_width_mm"]) == (first["id"], width)
    # the session's id shows that session
    page.click(f"#scale-current button:has-text('{first['id']}')")
    page.wait_for_function(
        "sid => document.querySelector('#session-id').textContent === sid", arg=first["id"]
    )
    assert visit.failed == []
    assert visit.console_errors == []
