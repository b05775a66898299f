"""Row 4 of issue 20: a calibration from the page's form to its results. The Kind list is the station's
(calibration was missing); the form is generated from the plan's schema, with the defaults shown and a
bad value refused beside its field; the results show the relative error before / after / floor, the
condition number and the identified count (an integer, not "39.0000"), the figures, and a CSV link that
answers (it was 409)."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import FINAL, api, open_page

# the small configuration: two of the cell's artifacts, three camera turns, four joint solutions (fewer
# solutions identify too little: the calibrated model misses by more than the nominal one, and the
# calibration's gate fails the session)
SMALL = {"placements": "[0, 1]", "turns_deg": "[-20, 70, 160]", "solutions": "4", "settle_s": "0"}


@pytest.mark.slow
@pytest.mark.timeout(600)
def test_a_calibration_runs_from_the_form_to_its_results(make_served: ServeFactory, browser: Any) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    with api(served.base) as c:
        kinds = c.get("/api/v1/station").json()["plans"]
    page.wait_for_function("document.querySelectorAll('#kind option').length > 0")
    assert page.eval_on_selector_all("#kind option", "os => os.map(o => o.value)") == kinds
    page.select_option("#kind", "calibration")
    # the form: one field per parameter, defaults shown
    page.wait_for_selector("#param-solutions")
    assert page.input_value("#param-solutions") == "4"
    assert page.input_value("#param-turns_deg") == "[-20,70,160,250]"  # a default computed by the plan
    assert page.input_value("#param-loss") == "linear"
    # a value out of range is refused beside its field, before anything is sent
    page.fill("#param-solutions", "9")
    assert "at most 8" in (page.text_content("#param-solutions-error") or "")
    posts = len([r for r in visit.requests if r.startswith("POST")])
    page.click("#start")
    assert "check the fields" in (page.text_content("#start-error") or "")
    assert len([r for r in visit.requests if r.startswith("POST")]) == posts
    for name, value in SMALL.items():
        page.fill(f"#param-{name}", value)
    assert page.text_content("#param-solutions-error") == ""
    page.click("#start")
    page.wait_for_function("document.querySelector('#session-kind').textContent === 'calibration'")
    sid = page.text_content("#session-id")
    assert visit.wait_state(*FINAL, timeout_ms=360_000) == "succeeded", page.text_content("#session-error")

    with api(served.base) as c:
        doc = c.get(f"/api/v1/sessions/{sid}").json()
    assert doc["params"]["plan"]["placements"] == [0, 1]
    assert doc["params"]["plan"]["solutions"] == 4
    results = doc["results"]
    page.wait_for_selector("#results-table")
    table = {
        row[0]: row[1]
        for row in page.eval_on_selector_all(
            "#results-table tr", "rows => rows.map(r => [...r.cells].map(c => c.textContent))"
        )
    }
    error = results["relative_error_um"]
    assert table["relative error before (nominal model)"] == f"{error['before']:.2f} µm"
    assert table["relative error after (calibrated model)"] == f"{error['after']:.2f} µm"
    assert table["relative error floor (the arm's repeatability)"] == f"{error['floor']:.2f} µm"
    assert table["condition number"] == f"{results['condition_number']:.1f}"
    assert re.fullmatch(r"\d+", table["parameters identified"])  # an integer shown as one
    assert int(table["parameters identified"]) == results["identified_count"]
    assert page.locator("#parameters-table tbody tr").count() == len(results["parameters"])
    # the report is written on the first request for its figures (the calibration's take a while)
    page.wait_for_function(
        "document.querySelectorAll('#figures img').length > 0 && "
        "[...document.querySelectorAll('#figures img')].every(i => i.complete && i.naturalWidth > 0)",
        timeout=180_000,
    )
    csv = page.locator("#report-links a", has_text="table (CSV)")
    href = csv.get_attribute("href")
    assert href is not None
    response = page.request.get(f"{served.base}{href}")
    assert response.status == 200
    lines = response.text().splitlines()
    assert lines[0].startswith("name,unit,nominal,estimate,interval_low,interval_high")
    assert len(lines) == 1 + len(results["parameters"])
    assert visit.failed == []
    assert visit.console_errors == []
