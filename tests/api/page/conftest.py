"""The operator page in a real headless Chromium (Debian's, driven by Playwright; never `playwright
install`), against a real service (uvicorn on 127.0.0.1 over the simulated station).

``Visit`` watches what a page does: console errors, uncaught exceptions, failed requests and every
response of 400 or more. Waits are on the page's own state (``wait_for_function``), never sleeps.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import pytest

from tests.api.conftest import AUTH, TOKEN
from tests.browser import chromium

WIDE = {"width": 1280, "height": 720}
NARROW = {"width": 800, "height": 900}
FINAL = ("succeeded", "failed", "aborted", "stopped", "interrupted")
PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]


@pytest.fixture(scope="module")
def chromium_process() -> Iterator[Any]:
    """One Chromium for a module's tests (Playwright's sync API runs one instance at a time per process:
    a module's is closed before the next module's, or ``tests/api/test_browser.py``'s, starts)."""
    with chromium() as b:
        yield b


@pytest.fixture
def browser(chromium_process: Any) -> Iterator[Any]:
    """Chromium for one test: the module's process, every browser context the test opened closed after
    it (a context is a fresh profile: cookies, storage and cache of its own), so that no page of one test
    still polls while the next runs."""
    yield chromium_process
    for context in list(chromium_process.contexts):
        context.close()


SNAPSHOT = "/api/v1/camera/snapshot.png"
"""The live view's picture of the camera between sessions (``api/static/js/live.js``)."""


@dataclass
class Visit:
    """A page and what went wrong in its browser context (the page and any it opened: a report)."""

    page: Any
    console_errors: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)
    busy: list[str] = field(default_factory=list)
    """The live view's snapshots the service answered 409: the page asked between two of its reads of the
    station while the arm set off (after an abort, the route to the reference pose); the page says "no new
    picture" and keeps the last one, which is the answer, not a failure."""

    def watch(self) -> Visit:
        context = self.page.context
        context.on("console", self._console)
        context.on("weberror", lambda e: self.console_errors.append(f"uncaught: {e.error}"))
        context.on("requestfailed", lambda r: self.failed.append(f"{r.method} {r.url}: {r.failure}"))
        context.on("request", lambda r: self.requests.append(f"{r.method} {r.url}"))
        context.on("response", self._response)
        return self

    def _console(self, message: Any) -> None:
        if message.type != "error":
            return
        # Chromium logs every 4xx answer as "Failed to load resource", located at the resource's URL: the
        # live view's busy snapshot is the answer described at ``busy``, any other is an error
        if "status of 409" in message.text and SNAPSHOT in (message.location or {}).get("url", ""):
            return
        self.console_errors.append(message.text)

    def _response(self, response: Any) -> None:
        if response.status == 409 and SNAPSHOT in response.url:
            self.busy.append(response.url)
        elif response.status >= 400:
            self.failed.append(f"{response.status} {response.url}")

    def state(self) -> str:
        return str(self.page.get_attribute("#state", "data-state"))

    def wait_state(self, *states: str, timeout_ms: int = 120_000) -> str:
        self.page.wait_for_function(
            "states => states.includes(document.querySelector('#state').dataset.state)",
            arg=list(states),
            timeout=timeout_ms,
        )
        return self.state()


def open_page(browser: Any, base: str, *, login: bool = True, viewport: dict[str, int] = WIDE) -> Visit:
    """A new page (its own cookies) on the service at ``base``; with ``login`` through the printed URL."""
    context = browser.new_context(viewport=viewport)
    visit = Visit(context.new_page()).watch()
    visit.page.set_default_timeout(60_000)
    if login:
        visit.page.goto(f"{base}/?token={TOKEN}")
        assert visit.page.url == f"{base}/"  # the token left the address bar
    else:
        visit.page.goto(f"{base}/")
    visit.page.wait_for_function("document.body.dataset.access !== 'unknown'")
    return visit


def start_from_form(visit: Visit, kind: str, params: dict[str, Any] | None = None) -> str:
    """Choose ``kind``, give ``params`` as the raw JSON (None: the form as it is), press Start; the new
    session's id (an AssertionError with the page's message when the service refused it)."""
    page = visit.page
    before = page.text_content("#session-id") or ""
    page.wait_for_function(
        "kind => [...document.querySelectorAll('#kind option')].some(o => o.value === kind)", arg=kind
    )
    page.select_option("#kind", kind)
    if params is not None:
        if not page.evaluate("document.querySelector('#raw-json').open"):
            page.click("#raw-json summary")
        page.fill("#params", json.dumps(params))
    page.click("#start")
    page.wait_for_function(
        """([kind, before]) => {
            const id = document.querySelector('#session-id').textContent;
            const shown = id && id !== before && document.querySelector('#session-kind').textContent === kind;
            return shown || document.querySelector('#start-error').textContent !== '';
        }""",
        arg=[kind, before],
    )
    refused = page.text_content("#start-error")
    assert not refused, refused
    sid = page.text_content("#session-id")
    assert sid
    return sid


def api(base: str) -> httpx.Client:
    return httpx.Client(base_url=base, headers=AUTH, timeout=60)
