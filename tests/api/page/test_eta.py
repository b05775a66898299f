"""Row 10 of issue 20: the ETA counts down while the session runs (it stood still between the service's
estimates) and says "paused" when paused (it showed a frozen time left)."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import FINAL, open_page, start_from_form

# every step waits settle_s after the arm arrives: steps of about two seconds, the ETA ticks within them
SLOW = {"cycles": 30, "joints": [1], "warmup_cycles": 0, "settle_s": 2.0}

# true once two readings of the progress text, for the same number of steps done, show different times
# left: the count went down between the service's estimates
COUNTS_DOWN = """() => {
    const text = document.querySelector('#progress-text').textContent;
    const m = /^(\\d+) \\/ (\\d+) steps, about (.+) left$/.exec(text);
    if (!m) return false;
    const prev = window.__eta || {};
    window.__eta = {done: m[1], left: m[3]};
    return prev.done === m[1] && prev.left !== undefined && prev.left !== m[3];
}"""


@pytest.mark.slow
@pytest.mark.timeout(240)
def test_the_eta_counts_down_while_running_and_says_paused(make_served: ServeFactory, browser: Any) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    start_from_form(visit, "repeatability", SLOW)
    visit.wait_state("running")
    page.wait_for_function("document.querySelector('#progress').value >= 2")
    page.wait_for_function(COUNTS_DOWN, polling=100, timeout=30_000)

    page.click("#pause")
    visit.wait_state("paused")
    text = page.text_content("#progress-text") or ""
    assert re.fullmatch(r"\d+ / 31 steps: paused", text), text
    assert "left" not in text
    page.click("#resume")
    visit.wait_state("running")
    page.evaluate("window.__eta = undefined")
    page.wait_for_function(COUNTS_DOWN, polling=100, timeout=30_000)

    page.click("#abort")
    page.click("#abort-yes")
    assert visit.wait_state(*FINAL) == "aborted"
    assert "left" not in (page.text_content("#progress-text") or "")
    assert visit.console_errors == []
