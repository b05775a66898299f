"""The page on a fresh station (issue 20, rows 8 and 10): the robot's state and pose from the start (it
showed "?" until the first session), the live measurement's numbers, no request known to fail before a
session's first capture, a favicon, and a clear read-only (or log-in) note without the token."""

from __future__ import annotations

import re
from typing import Any

import pytest

from tests.api.conftest import ServeFactory
from tests.api.page.conftest import FINAL, api, open_page, start_from_form

NUMBERS = "document.querySelector('#live-numbers').textContent"


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_the_robot_is_shown_from_the_start(make_served: ServeFactory, browser: Any) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    with api(served.base) as c:
        assert c.get("/api/v1/sessions").json()["total"] == 0  # no session has connected the robot
    page.wait_for_function("document.querySelector('#robot-section').dataset.state === 'idle'")
    state = page.text_content("#robot-state") or ""
    assert state.startswith("A465: idle, power on, homed, at the reference pose"), state
    assert re.search(
        r"joints 0, 30, 60, 0, 90, 0° \(read \d\d:\d\d:\d\d\)", page.text_content("#robot-pose") or ""
    )
    assert page.is_hidden("#to-reference")  # at its reference pose: nothing to offer
    robot = page.text_content("#devices li[data-device='robot']") or ""
    assert robot.startswith("robot: A465")
    assert "?" not in robot
    assert visit.failed == []


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_the_live_view_shows_the_measurement_numbers(make_served: ServeFactory, browser: Any) -> None:
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    # between sessions: the camera now, its measurement's centre in px and mm
    page.wait_for_function(f"{NUMBERS}.includes('centre (px)')")
    numbers = page.text_content("#live-numbers") or ""
    assert re.search(r"centre \(px\)x -?\d+\.\d{3}, y -?\d+\.\d{3}", numbers), numbers
    assert re.search(r"centre \(mm\)x -?\d+\.\d{4}, y -?\d+\.\d{4}", numbers), numbers
    # in a session: each capture's, with which capture it is
    start_from_form(visit, "repeatability", {"cycles": 3, "joints": [1], "warmup_cycles": 0})
    page.wait_for_function(f"{NUMBERS}.includes('capture ')")
    numbers = page.text_content("#live-numbers") or ""
    assert "centre (mm)" in numbers
    assert "distance (mm)" in numbers  # the sim has a Z sensor: its reading with the capture
    assert visit.wait_state(*FINAL) == "succeeded"
    assert visit.failed == []


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_session_start_makes_no_request_that_fails(make_served: ServeFactory, browser: Any) -> None:
    """Row 8: the page asked for ``latest.png`` before the first capture (409s), had no favicon (404) and
    logged console errors for each."""
    served = make_served()
    visit = open_page(browser, served.base)
    page = visit.page
    page.wait_for_function(f"{NUMBERS} !== ''")  # the idle view is in
    start_from_form(visit, "repeatability", {"cycles": 4, "joints": [1, 2], "warmup_cycles": 0})
    assert visit.wait_state(*FINAL) == "succeeded"
    page.wait_for_selector("#tests-table")
    latest = [r for r in visit.requests if "/latest.png" in r]
    assert latest  # the live view followed the session's captures
    assert visit.failed == []
    assert visit.console_errors == []
    icon = page.request.get(f"{served.base}/favicon.ico")
    assert icon.status == 200
    assert icon.headers["content-type"].startswith("image/")
    assert page.evaluate("document.querySelector('link[rel=icon]').href").endswith("/static/favicon.svg")


@pytest.mark.slow
@pytest.mark.timeout(180)
@pytest.mark.parametrize("open_reads", [True, False])
def test_without_login_the_page_says_so_before_anything_fails(
    make_served: ServeFactory, browser: Any, open_reads: bool
) -> None:
    served = make_served(public_read=open_reads)
    visit = open_page(browser, served.base, login=False)
    page = visit.page
    page.wait_for_selector("#auth-note:not([hidden])")
    note = page.text_content("#auth-note") or ""
    if open_reads:
        assert note.startswith("Read-only: open the login URL that station serve printed")
        page.wait_for_function("document.querySelectorAll('#kind option').length > 0")
        page.wait_for_function("document.querySelector('#robot-section').dataset.state === 'idle'")
        for control in ("#start", "#kind", "#to-reference"):
            assert page.is_disabled(control), control
    else:
        assert note.startswith("Not logged in: open the login URL that station serve printed")
    assert page.evaluate("document.body.dataset.access") == ("read" if open_reads else "none")
    assert visit.failed == []  # no 401: nothing was asked that needs the token
    assert visit.console_errors == []
