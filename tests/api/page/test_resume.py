"""Rows 3 and 6 of issue 20: an aborted repeatability is resumed from the page (Resume was disabled for
``failed``, ``stopped`` and ``aborted`` although the API resumes them), and its step count continues
instead of restarting at 0: from the tests that stay done, since a resume reruns the interrupted test
from its start (issue 19: no population mixes two runs)."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import FINAL, api, open_page, start_from_form

CYCLES = 15
STEPS_PER_TEST = 1 + CYCLES  # the reference, the cycles


def counts(text: str | None) -> tuple[int, int]:
    found = re.match(r"(\d+) / (\d+) steps", text or "")
    assert found, text
    return int(found.group(1)), int(found.group(2))


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_an_aborted_repeatability_is_resumed_from_the_page_and_continues_its_count(
    make_served: ServeFactory, browser: Any
) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    sid = start_from_form(visit, "repeatability", {"cycles": CYCLES, "joints": [1, 2], "warmup_cycles": 0})
    # J1 done, J2 under way
    page.wait_for_function(f"document.querySelector('#progress').value >= {STEPS_PER_TEST + 3}")
    page.click("#abort")
    assert "The arm stops now" in (page.inner_text("#abort-confirm") or "")
    page.click("#abort-yes")
    assert visit.wait_state(*FINAL) == "aborted"
    done, total = counts(page.text_content("#progress-text"))
    assert STEPS_PER_TEST + 3 <= done < total == 2 * STEPS_PER_TEST
    page.wait_for_function("!document.querySelector('#resume').disabled")
    # an operator looks at what it measured first (its partial results and figures)
    page.wait_for_selector("#results-state")
    assert "Its results below are partial" in (page.text_content("#results-state") or "")
    page.wait_for_function("document.querySelectorAll('#figures img').length > 0")
    note = page.text_content("#control-note") or ""
    assert "Resume continues this session: it reruns the interrupted test from its start" in note

    # the abort latched the robot's stop: the operator at the station acknowledges it in the Robot panel
    page.wait_for_selector("#latch", state="visible")
    assert "A stop is latched" in (page.text_content("#latch-text") or "")
    page.wait_for_function("!document.querySelector('#acknowledge').disabled")
    assert page.is_hidden("#latch-remote")  # this page runs on the station itself (loopback)
    page.click("#acknowledge")
    page.wait_for_selector("#latch", state="hidden")
    assert "stop acknowledged at the station" in (page.text_content("#robot-message") or "")

    page.click("#resume")
    # the same session runs again, its count going on from where it stopped
    page.wait_for_function(
        """sid => document.querySelector('#session-id').textContent === sid
            && ['running', 'succeeded'].includes(document.querySelector('#state').dataset.state)""",
        arg=sid,
    )
    assert page.text_content("#session-id") == sid
    again, total_again = counts(page.text_content("#progress-text"))
    assert again >= STEPS_PER_TEST  # J1's steps stay done; J2 runs again from its start
    assert total_again == total
    assert visit.wait_state(*FINAL) == "succeeded", page.text_content("#session-error")
    assert counts(page.text_content("#progress-text")) == (total, total)
    with api(served.base) as c:
        doc = c.get(f"/api/v1/sessions/{sid}").json()
    assert doc["state"] == "succeeded"
    assert doc["progress"]["done"] == doc["progress"]["total"] == total
    page.wait_for_selector("#tests-table")
    rows = page.eval_on_selector_all("#tests-table tbody tr", "rs => rs.map(r => r.textContent)")
    assert [r[:2] for r in rows] == ["J1", "J2"]
    for test, row in zip(("J1", "J2"), rows, strict=True):
        assert doc["results"]["tests"][test]["n_cycles"] == CYCLES  # J2's abandoned cycles left out
        assert str(CYCLES) in row
        assert "partial" not in row
    assert visit.failed == []
    assert visit.console_errors == []
