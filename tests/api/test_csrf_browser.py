"""Cross-site requests in a real browser (issue 18, row 3): Debian's headless Chromium, driven by
Playwright as in ``test_browser.py``.

The operator logs in to the station; a page served from another port of the same host then posts an
exported session to the station's import with ``mode: "no-cors"``, ``credentials: "include"`` and a
``text/plain`` body. ``SameSite=Strict`` does not separate ports, so the browser sends the login cookie:
the station must refuse the request itself (its Origin is not the station's), and import nothing.
Also: the page without a login says how to log in.
"""

from __future__ import annotations

import io
import threading
import zipfile
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import pytest

from station.record import Record
from station.session import run_session
from tests.api.conftest import TOKEN, ServeFactory
from tests.browser import chromium

ATTACK = """<!doctype html><title>pending</title><script>
fetch("/payload.zip").then(r => r.arrayBuffer()).then(zip =>
  fetch("%(station)s/api/v1/sessions/import", {
    method: "POST", mode: "no-cors", credentials: "include",
    headers: {"Content-Type": "text/plain"}, body: zip,
  })
).then(() => { document.title = "sent"; }, e => { document.title = "error " + e; });
</script>"""


@pytest.fixture
def browser() -> Iterator[Any]:
    with chromium() as b:
        yield b


def exported_session(tmp_path: Path) -> tuple[str, bytes]:
    """A session of another station, as the zip ``/export.zip`` gives."""
    outcome = run_session(
        "repeatability",
        sim=True,
        params={"cycles": 2, "joints": [1], "warmup_cycles": 0},
        data=tmp_path / "other",
    )
    with Record(tmp_path / "other") as record:
        folder = record.export_session(outcome.id, tmp_path / "export")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for path in sorted(folder.rglob("*")):
            if path.is_file():
                zf.write(path, Path(outcome.id) / path.relative_to(folder))
    return outcome.id, buf.getvalue()


class AttackerSite:
    """A web site on another port of this host: its page, and the zip it posts."""

    def __init__(self, station: str, payload: bytes) -> None:
        page = (ATTACK % {"station": station}).encode()

        class Handler(BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                body, ctype = (
                    (payload, "application/zip") if self.path == "/payload.zip" else (page, "text/html")
                )
                self.send_response(200)
                self.send_header("Content-Type", ctype)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, format: str, *args: Any) -> None:
                pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.server.shutdown()
        self.server.server_close()


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_page_on_another_port_cannot_use_the_operators_cookie(
    make_served: ServeFactory, browser: Any, tmp_path: Path
) -> None:
    sid, payload = exported_session(tmp_path)
    served = make_served(sim=False)
    attacker = AttackerSite(served.base, payload)
    try:
        page = browser.new_page()
        page.set_default_timeout(60_000)
        page.goto(f"{served.base}/?token={TOKEN}")  # the operator logs in
        assert page.url == f"{served.base}/"
        with page.expect_response(lambda r: r.url.endswith("/api/v1/sessions/import")) as answered:
            page.goto(attacker.url)  # ... and later opens another page on this host
        page.wait_for_function("document.title !== 'pending'")
        assert page.title() == "sent"  # the browser did send it (with the cookie: same site)
        response = answered.value
        # 403 (cross_origin), not 401: the browser sent the login cookie, and the Origin refused it
        assert response.status == 403, response.status
    finally:
        attacker.close()
    with served.client() as c:
        assert c.get("/api/v1/sessions").json()["total"] == 0
        assert c.get(f"/api/v1/sessions/{sid}").status_code == 404
    assert not (served.service.record.data_dir / "images" / sid).exists()


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_page_without_a_login_says_how_to_log_in(make_served: ServeFactory, browser: Any) -> None:
    served = make_served(sim=False)
    page = browser.new_page()
    page.set_default_timeout(60_000)
    page.goto(f"{served.base}/")
    page.wait_for_selector("#auth-note", state="visible")
    note = page.text_content("#auth-note") or ""
    assert "login URL" in note
    assert "station serve" in note
