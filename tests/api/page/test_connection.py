"""Row 1 of issue 20: the service is killed during a session. The page must not keep showing a green
``running`` with enabled buttons: within 5 s it says "service unreachable since HH:MM:SS", greys every
control and marks the state unknown; once the service is back it reconnects by itself, re-reads the
state (the session is now ``interrupted``) and clears the banner.

The service is a real ``station serve`` process, killed with SIGKILL and started again on the same port.
"""

from __future__ import annotations

import os
import re
import socket
import time
from pathlib import Path
from typing import Any

import pytest

from tests.api.conftest import TOKEN
from tests.api.page.conftest import api, open_page
from tests.api.test_serve import ServeProcess

LONG = {"cycles": 5000, "joints": [1], "warmup_cycles": 0}
CONTROLS = ["#pause", "#resume", "#stop", "#abort", "#start", "#kind"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def serve(data: Path, port: int) -> ServeProcess:
    proc = ServeProcess(data, "--port", str(port), env={"STATION_API_TOKEN": TOKEN})
    proc.wait_url()
    return proc


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_killed_service_shows_as_unreachable_and_the_page_recovers(tmp_path: Path, browser: Any) -> None:
    port = free_port()
    first = serve(tmp_path / "data", port)
    base = f"http://127.0.0.1:{port}"
    second: ServeProcess | None = None
    try:
        visit = open_page(browser, base)
        page = visit.page
        page.select_option("#kind", "repeatability")
        page.click("#raw-json summary")
        page.fill("#params", str(LONG).replace("'", '"'))
        page.click("#start")
        visit.wait_state("running")
        page.wait_for_function("document.querySelector('#progress').value >= 2")
        sid = page.text_content("#session-id")
        with api(base) as c:
            worker_pid = c.get("/api/v1/station").json()["worker"]["pid"]
        assert page.evaluate("document.body.dataset.connection") == "ok"

        first.proc.kill()  # SIGKILL: no shutdown, no goodbye on the event stream
        killed = time.monotonic()
        page.wait_for_function("document.body.dataset.connection === 'lost'", timeout=5_000)
        assert time.monotonic() - killed < 5.0
        banner = page.text_content("#connection-banner") or ""
        assert re.search(r"service unreachable since \d\d:\d\d:\d\d", banner), banner
        assert page.is_visible("#connection-banner")
        assert visit.state() == "unknown"
        assert "running" not in (page.text_content("#state") or "")
        assert "left" not in (page.text_content("#progress-text") or "")  # no ETA for an unknown state
        for selector in CONTROLS:
            assert page.is_disabled(selector), selector

        first.finish()
        while not gone(worker_pid):  # the worker records the session interrupted and lets go of the lock
            time.sleep(0.1)
        second = serve(tmp_path / "data", port)

        # the page reconnects by itself: the banner goes, the state is read again
        page.wait_for_function("document.body.dataset.connection === 'ok'", timeout=30_000)
        assert page.is_hidden("#connection-banner")
        assert visit.wait_state("interrupted", timeout_ms=30_000) == "interrupted"
        assert page.text_content("#session-id") == sid
        assert page.is_enabled("#resume")  # the API resumes an interrupted session
        assert page.is_enabled("#start")
        page.wait_for_function("document.querySelector('#live').naturalWidth > 0")
    finally:
        for proc in (first, second):
            if proc is not None:
                if proc.proc.poll() is None:
                    proc.interrupt()  # Ctrl-C: the service shuts its worker down in order
                else:
                    proc.finish()
