"""Chromium for the page's browser tests and the screenshot bench: Debian's ``/usr/bin/chromium`` driven
by Playwright (never ``playwright install``), with the flags a container without a GPU or a shared-memory
mount needs."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
]


@contextmanager
def chromium() -> Iterator[Any]:
    """A headless Chromium (Playwright's sync API runs one at a time per process); a test skips where
    Playwright or Chromium is missing, saying what to install."""
    from tests.conftest import needs_system

    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        needs_system("playwright (pip)", False, "pip install playwright")
        raise
    needs_system("chromium", shutil.which(CHROMIUM) is not None, "apt-get install chromium")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
        try:
            yield browser
        finally:
            browser.close()


def confirm_prompt(page: Any) -> None:
    """Confirm the operator prompt the page shows, then wait until its panel is gone or shows another
    prompt (the next one, opened at once by the same step)."""
    prompt_id = page.get_attribute("#prompt-panel", "data-prompt-id")
    page.click("#prompt-confirm")
    page.wait_for_function(
        "id => document.querySelector('#prompt-panel').hidden || "
        "document.querySelector('#prompt-panel').dataset.promptId !== id",
        arg=prompt_id,
    )
