"""A person runs a validation in the page from the form to the report (--manual-prompts: they answer
every micrometer prompt): each prompt says which position of how many and whether it is the overshoot
before a backwards move, in inches with mm in brackets; the visit has no console error and no failed
request (issue 20, row 9 and the clean visit)."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import FINAL, PATTERN, open_page, start_from_form
from tests.browser import confirm_prompt

PROMPT_OR_END = (
    "!document.querySelector('#prompt-panel').hidden || "
    "['succeeded','failed','aborted','stopped','interrupted'].includes(document.querySelector('#state').dataset.state)"
)


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_validation_visit_from_start_to_report_is_clean(make_served: ServeFactory, browser: Any) -> None:
    served = make_served(manual=True)
    visit = open_page(browser, served.base)
    page = visit.page
    sid = start_from_form(visit, "validation", {"pattern_um": PATTERN})
    said: list[tuple[int, int, str]] = []
    while True:
        page.wait_for_function(PROMPT_OR_END)
        if page.is_hidden("#prompt-panel"):
            break
        title = page.text_content("#prompt-title") or ""
        message = page.text_content("#prompt-message") or ""
        if title == "Operator: what lies on the X-Y table":  # first the cross on the table, then the table
            assert not said
            assert message.startswith("Put the artifact's cross on the X-Y table"), message
            said.append((0, 0, "cross"))
            confirm_prompt(page)
            continue
        found = re.search(r"position (\d+) of (\d+)", title)
        assert found, title
        move = str(page.get_attribute("#prompt-panel", "data-move"))
        said.append((int(found.group(1)), int(found.group(2)), move))
        # every length in the table's unit (inches), the table position in mm in brackets
        assert re.search(r"set X to \d\.\d{4} in, Y to \d\.\d{4} in", message), message
        assert re.search(r"\(table at X -?\d+\.\d{4} mm, Y -?\d+\.\d{4} mm\)", message), message
        assert page.input_value("input[name=x_in]").count(".") == 1
        assert len(page.input_value("input[name=x_in]").split(".")[1]) == 4  # the micrometer's 0.0001 in
        assert re.fullmatch(r"\(-?\d+\.\d{4} mm\)", page.text_content("#prompt-field-x_in-mm") or "")
        if move == "overshoot":
            assert "Overshoot before a backwards move" in (page.text_content("#prompt-move") or "")
        confirm_prompt(page)
    assert visit.wait_state(*FINAL) == "succeeded", page.text_content("#session-error")
    # the cross on the table, then 6 prompts for 4 positions: an overshoot before the first and before
    # the move back in -x
    assert said == [
        (0, 0, "cross"),
        (1, 4, "overshoot"),
        (1, 4, "position"),
        (2, 4, "position"),
        (3, 4, "position"),
        (4, 4, "overshoot"),
        (4, 4, "position"),
    ]
    page.wait_for_selector("#results-table")
    assert "mean error" in (page.text_content("#results-table") or "")
    assert page.locator("#positions-table tbody tr").count() == len(PATTERN)
    page.wait_for_function(
        "document.querySelectorAll('#figures img').length > 0 && "
        "[...document.querySelectorAll('#figures img')].every(i => i.complete && i.naturalWidth > 0)"
    )
    assert page.text_content("#progress-text") == "4 / 4 steps"
    # the report, opened from the page: its figure files load from the API
    with page.context.expect_page() as opened:
        page.click("#report-links a:text-is('HTML report')")
    report = opened.value
    report.wait_for_load_state()
    assert sid in (report.title() or "")
    hrefs = report.eval_on_selector_all("figcaption a", "links => links.map(a => a.href)")
    assert hrefs
    assert all(f"/api/v1/sessions/{sid}/figures/" in h for h in hrefs), hrefs
    for href in hrefs:
        response = report.goto(href)
        assert response is not None
        assert response.status == 200, href
    assert visit.console_errors == []
    assert visit.failed == []
    assert any(r.endswith("/static/favicon.svg") for r in visit.requests)
