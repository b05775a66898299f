"""Row 2 of issue 20: while a micrometer prompt is open the operator is never trapped. The prompt is a
panel beside the live view, not a modal: Pause, Stop and Abort stay usable. Its Cancel asks first and
says what it does; cancelled, the session stops with a message in the table's unit (inches, mm in
brackets), not in mm alone."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import PATTERN, api, open_page, start_from_form
from tests.browser import confirm_prompt

OPEN = "!document.querySelector('#prompt-panel').hidden"


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_prompt_leaves_the_controls_usable_and_cancel_asks_first(
    make_served: ServeFactory, browser: Any
) -> None:
    served = make_served(manual=True)
    visit = open_page(browser, served.base)
    page = visit.page
    sid = start_from_form(visit, "validation", {"pattern_um": PATTERN})
    # first the station asks for the artifact's cross on the X-Y table (it knows nothing of it yet)
    page.wait_for_function(OPEN)
    visit.wait_state("awaiting_operator")
    assert page.text_content("#prompt-title") == "Operator: what lies on the X-Y table"
    message = page.text_content("#prompt-message") or ""
    assert message.startswith("Put the artifact's cross on the X-Y table")
    assert "does not know what lies there" in (page.text_content("#prompt-move") or "")
    confirm_prompt(page)
    page.wait_for_function(OPEN)  # the step's first table prompt
    visit.wait_state("awaiting_operator")
    # nothing modal: no open <dialog>, and the session's controls take real clicks (Playwright refuses to
    # click an element another covers, or one a modal dialog makes inert)
    assert page.evaluate("[...document.querySelectorAll('dialog')].every(d => !d.open)")
    page.click("#pause", timeout=5_000)
    note = "document.querySelector('#control-note').textContent"
    page.wait_for_function(f"{note}.includes('at the end of this step')")
    with api(served.base) as c:
        assert c.get(f"/api/v1/sessions/{sid}").json()["state"] == "awaiting_operator"
    assert page.is_enabled("#stop")
    assert page.is_enabled("#abort")

    # the step's prompts answered (the overshoot, then the position): the session pauses at its end;
    # Resume continues to the next position's prompt
    while visit.state() != "paused":
        page.wait_for_function(f"{OPEN} || document.querySelector('#state').dataset.state === 'paused'")
        if page.is_visible("#prompt-panel"):
            confirm_prompt(page)
    assert page.text_content("#progress-text") == "1 / 4 steps: paused"
    page.click("#resume")
    page.wait_for_function(OPEN)

    # Cancel asks first and says what it does; "No" keeps the prompt and the session
    prompt_id = page.get_attribute("#prompt-panel", "data-prompt-id")
    page.click("#prompt-cancel")
    question = " ".join((page.inner_text("#prompt-cancel-confirm") or "").split())
    assert "The session will stop; the table stays where it is." in question
    assert page.is_visible("#prompt-cancel-confirm")
    page.click("#prompt-cancel-no")
    assert page.is_hidden("#prompt-cancel-confirm")
    with api(served.base) as c:
        assert c.get("/api/v1/prompt").json()["id"] == prompt_id
        assert c.get(f"/api/v1/sessions/{sid}").json()["state"] == "awaiting_operator"

    # confirmed: the move is cancelled, the session stops and says where the table is, in inches
    page.click("#prompt-cancel")
    page.click("#prompt-cancel-yes")
    assert visit.wait_state("failed") == "failed"
    error = page.text_content("#session-error") or ""
    assert "cancelled" in error
    assert re.search(
        r"last confirmed position is X \d\.\d{4} in, Y \d\.\d{4} in \(X -?\d+\.\d{4} mm", error
    ), error
    assert page.is_hidden("#prompt-panel")
    assert page.is_enabled("#resume")  # it can be continued from its last completed position
    assert visit.failed == []
    assert visit.console_errors == []
