"""The operator page in a real headless Chromium (Debian's, driven by Playwright): a person logs in with
the printed URL, runs a validation answering every micrometer prompt in the page (--manual-prompts),
sees the result table and figures, and aborts a repeatability session. Under CI=true it must run.
The page's behaviour in detail (issue 20) is tested in ``tests/api/page/``."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from tests.api.conftest import TOKEN, ServeFactory
from tests.browser import chromium, confirm_prompt

PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


@pytest.fixture
def browser() -> Iterator[Any]:
    with chromium() as b:
        yield b


def login(browser: Any, base: str) -> Any:
    page = browser.new_page()
    page.set_default_timeout(60_000)
    page.goto(f"{base}/?token={TOKEN}")
    assert page.url == f"{base}/"  # the token left the address bar
    page.wait_for_selector("#station-name:not(:empty)")
    return page


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_person_runs_a_validation_in_the_page(make_served: ServeFactory, browser: Any) -> None:
    served = make_served(manual=True)
    page = login(browser, served.base)
    page.select_option("#kind", "validation")
    page.click("#raw-json summary")
    page.fill("#params", json.dumps({"pattern_um": PATTERN}))
    page.click("#start")
    answered = 0
    while True:
        page.wait_for_function(
            "!document.querySelector('#prompt-panel').hidden || "
            "['succeeded','failed','aborted','stopped'].includes(document.querySelector('#state').dataset.state)"
        )
        if page.is_hidden("#prompt-panel"):
            break
        message = page.text_content("#prompt-message")
        assert message is not None
        if message.startswith("Put the artifact's cross on the X-Y table"):  # asked first, no readings
            assert answered == 0
            confirm_prompt(page)
            continue
        assert "set X to" in message
        x_in = page.input_value("input[name=x_in]")
        assert len(x_in.split(".")[1]) == 4  # inches, to the micrometer's 0.0001 in
        confirm_prompt(page)
        answered += 1
    assert page.get_attribute("#state", "data-state") == "succeeded", page.text_content("#session-error")
    assert answered >= len(PATTERN)
    page.wait_for_selector("#results-table")
    assert "mean error" in (page.text_content("#results-table") or "")
    assert page.locator("#positions-table tr").count() == len(PATTERN) + 1
    page.wait_for_function(
        "document.querySelectorAll('#figures img').length > 0 && "
        "[...document.querySelectorAll('#figures img')].every(i => i.complete && i.naturalWidth > 0)"
    )
    page.wait_for_selector("#sessions tbody tr")
    assert "succeeded" in (page.text_content("#sessions tbody") or "")


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_person_aborts_a_repeatability_from_the_page(make_served: ServeFactory, browser: Any) -> None:
    served = make_served()
    page = login(browser, served.base)
    page.select_option("#kind", "repeatability")
    page.click("#raw-json summary")
    page.fill("#params", '{"cycles": 5000, "joints": [1]}')
    page.click("#start")
    page.wait_for_function("document.querySelector('#state').dataset.state === 'running'")
    page.wait_for_function("document.querySelector('#live').naturalWidth > 0")
    page.click("#abort")
    page.click("#abort-yes")  # "Abort the session?"
    page.wait_for_function("document.querySelector('#state').dataset.state === 'aborted'")
    sid = page.text_content("#session-id")
    assert sid is not None
    assert served.service.record.get_session(sid).state == "aborted"
    assert page.is_enabled("#start")
