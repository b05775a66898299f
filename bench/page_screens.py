"""Screenshots of the operator page, for a person to look at (issue 20): at 1280x720 and 800 px wide, the
idle page (with the scale calibration and its history), a micrometer prompt, a running session, each
kind's results (validation, repeatability, calibration, sweep, re-analysis, a session refused at
pre-flight, a validation its gates failed, a repeatability with partial tests), the route to the
reference pose offered after a calibration, and the lost-connection banner.

``python -m bench.page_screens [--out out/page] [--cycles 10]``: a service on the simulated station with
``--manual-prompts`` (this script answers the validation's prompts through the API, as a person does in
the page), sessions of every kind through the API, then Debian's Chromium through Playwright (never
``playwright install``). The PNGs go to ``--out`` (not committed); it prints their names and how long
each part took. The banner comes last: the HTTP server is stopped under the open pages.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, cast

import httpx

from tests.browser import ARGS, CHROMIUM

TOKEN = "bench-page-token-0123456789abcdef"
VIEWPORTS = {"1280": {"width": 1280, "height": 720}, "800": {"width": 800, "height": 900}}
PATTERN = [[0.0, 0.0], [254.0, 0.0], [254.0, 254.0], [0.0, 254.0]]
# four joint solutions: with two, the calibrated model misses by more than the nominal one and the
# calibration's gate fails the session
SMALL_CALIBRATION = {"placements": [0, 1], "turns_deg": [-20.0, 70.0, 160.0], "solutions": 4, "settle_s": 0.0}
FINAL = {"stopped", "aborted", "failed", "succeeded", "interrupted"}


@contextmanager
def service(data: Path) -> Iterator[tuple[Any, Any, str]]:
    """The simulated station with --manual-prompts behind uvicorn on 127.0.0.1: (service, server, base)."""
    import uvicorn

    from api import Access, ServiceSettings, StationService, create_app

    svc = StationService(ServiceSettings(sim=True, manual_prompts=True, data=data, sim_options={"seed": 0}))
    server = uvicorn.Server(
        uvicorn.Config(
            create_app(svc, Access(TOKEN, True)),
            host="127.0.0.1",
            port=0,
            access_log=False,
            log_config=None,
            lifespan="on",
            timeout_graceful_shutdown=2,
        )
    )
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    while not server.started:
        time.sleep(0.01)
    try:
        yield svc, server, f"http://127.0.0.1:{server.servers[0].sockets[0].getsockname()[1]}"
    finally:
        server.should_exit = True
        thread.join(30)
        svc.close()


def run(c: httpx.Client, kind: str, params: dict[str, Any], *, answer: bool = False) -> str:
    """Create a session and wait for its end, confirming every prompt at its requested readings."""
    r = c.post("/api/v1/sessions", json={"kind": kind, "params": params})
    r.raise_for_status()
    sid: str = r.json()["id"]
    while c.get(f"/api/v1/sessions/{sid}").json()["state"] not in FINAL:
        if answer:
            p = c.get("/api/v1/prompt")
            if p.status_code == 200:
                doc = p.json()
                readings = {f["name"]: f["requested"] for f in doc["fields"]}
                c.post(f"/api/v1/prompt/{doc['id']}/confirm", json={"readings": readings})
                continue
        time.sleep(0.1)
    return sid


def run_partial(c: httpx.Client, params: dict[str, Any], steps: int) -> str:
    """A repeatability aborted once ``steps`` of its steps are done: its later tests are partial."""
    r = c.post("/api/v1/sessions", json={"kind": "repeatability", "params": params})
    r.raise_for_status()
    sid: str = r.json()["id"]
    while c.get(f"/api/v1/sessions/{sid}").json()["progress"]["done"] < steps:
        time.sleep(0.05)
    c.post(f"/api/v1/sessions/{sid}/actions", json={"action": "abort"}).raise_for_status()
    while c.get(f"/api/v1/sessions/{sid}").json()["state"] not in FINAL:
        time.sleep(0.1)
    return sid


def wait_for(page: Any, script: str, arg: Any = None, timeout_ms: int = 120_000) -> None:
    page.wait_for_function(script, arg=arg, timeout=timeout_ms)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/page", help="folder for the PNGs (default out/page)")
    parser.add_argument("--cycles", type=int, default=10, help="repeatability cycles per test")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    from playwright.sync_api import sync_playwright

    timings: dict[str, float] = {}
    written: list[str] = []
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory() as tmp, service(Path(tmp) / "data") as (_svc, server, base):
        headers = {"Authorization": f"Bearer {TOKEN}"}
        with httpx.Client(base_url=base, headers=headers, timeout=120) as c:
            sessions = {"validation": run(c, "validation", {"pattern_um": PATTERN}, answer=True)}
            sessions["repeatability"] = run(
                c, "repeatability", {"cycles": args.cycles, "joints": [1, 2, 3], "warmup_cycles": 0}
            )
            sessions["sweep"] = run(
                c, "sweep", {"session": sessions["validation"], "grid": {"testwidth": [3, 5, 7]}}
            )
            sessions["reanalyse"] = run(c, "reanalyse", {"session": sessions["validation"]})
            far = {"S1": [[0, 30, 60, 0, 90, 0], [75, 30, 60, 0, 90, 0]]}  # refused at pre-flight
            refused = {"kind": "repeatability", "params": {"joints": [], "sequences": far}}
            assert c.post("/api/v1/sessions", json=refused).status_code == 422
            sessions["failed"] = c.get("/api/v1/sessions", params={"limit": 1}).json()["items"][0]["id"]
            # a second validation (the scale calibration's history has two) and one its gates refuse
            run(c, "validation", {"pattern_um": PATTERN}, answer=True)
            tight = {"pattern_um": PATTERN, "mean_limit_um": 0.01, "max_limit_um": 0.02}
            sessions["gates-failed"] = run(c, "validation", tight, answer=True)
            cycles = args.cycles
            sessions["partial"] = run_partial(
                c, {"cycles": cycles, "joints": [1, 2, 3], "warmup_cycles": 0}, steps=cycles + 4
            )
            timings["sessions_s"] = round(time.monotonic() - t0, 1)

            t1 = time.monotonic()
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=ARGS)
                pages: dict[str, Any] = {}
                for name, viewport in VIEWPORTS.items():
                    page = browser.new_context(viewport=cast(Any, viewport)).new_page()
                    page.set_default_timeout(120_000)
                    page.goto(f"{base}/?token={TOKEN}")
                    pages[name] = page

                def shot(label: str, *, full: bool = False) -> None:
                    for name, page in pages.items():
                        path = out / f"{label}-{name}.png"
                        page.screenshot(path=str(path), full_page=full)
                        written.append(path.name)

                def top() -> None:
                    for page in pages.values():
                        page.evaluate("window.scrollTo(0, 0)")

                for page in pages.values():
                    wait_for(page, "document.querySelector('#live-numbers').textContent !== ''")
                    wait_for(page, "document.querySelector('#robot-section').dataset.state === 'idle'")
                top()
                shot("idle")

                # a prompt: the validation's first (the overshoot before position 1)
                new = {"kind": "validation", "params": {"pattern_um": PATTERN}}
                c.post("/api/v1/sessions", json=new).raise_for_status()
                for page in pages.values():
                    wait_for(page, "!document.querySelector('#prompt-panel').hidden")
                top()
                shot("prompt")
                prompt = c.get("/api/v1/prompt").json()
                c.post(f"/api/v1/prompt/{prompt['id']}/cancel", json={"reason": "screenshots"})
                while c.get("/api/v1/station").json()["session"] is not None:
                    time.sleep(0.1)

                # a running session
                long = {
                    "kind": "repeatability",
                    "params": {"cycles": 2000, "joints": [1], "warmup_cycles": 0},
                }
                running = c.post("/api/v1/sessions", json=long)
                running.raise_for_status()
                for page in pages.values():
                    wait_for(page, "document.querySelector('#progress').value >= 3")
                    wait_for(page, "document.querySelector('#live-numbers').textContent.includes('capture')")
                    wait_for(
                        page, "/about .+ left/.test(document.querySelector('#progress-text').textContent)"
                    )
                top()
                shot("running")
                c.post(f"/api/v1/sessions/{running.json()['id']}/actions", json={"action": "abort"})
                while c.get("/api/v1/station").json()["session"] is not None:
                    time.sleep(0.1)

                # the calibration last: it leaves the arm away from its reference pose
                sessions["calibration"] = run(c, "calibration", SMALL_CALIBRATION)
                shown = "sid => document.querySelector('#session-id').textContent === sid"
                for kind, sid in sessions.items():
                    for page in pages.values():
                        page.click(f"#sessions tr[data-id='{sid}'] .row-open")
                        wait_for(page, shown, sid)
                        wait_for(page, "!document.querySelector('#results-section').hidden")
                        wait_for(
                            page,
                            "sid => document.querySelector('#figures').dataset.loaded?.startsWith(sid) && "
                            "[...document.querySelectorAll('#figures img')].every(i => i.complete)",
                            sid,
                        )
                    shot(f"results-{kind}", full=True)

                # the arm away from its reference pose (after the calibration): the route, before moving
                for page in pages.values():
                    wait_for(page, "!document.querySelector('#to-reference').hidden")
                    page.click("#to-reference")
                    wait_for(page, "document.querySelector('#to-reference-route').dataset.route === 'ok'")
                    page.evaluate("document.querySelector('#robot-section').scrollIntoView()")
                shot("to-reference")

                # the service goes away under the open pages: the banner
                server.should_exit = True
                for page in pages.values():
                    wait_for(page, "document.body.dataset.connection === 'lost'", timeout_ms=10_000)
                top()
                shot("lost")
                browser.close()
            timings["screenshots_s"] = round(time.monotonic() - t1, 1)
    for name in written:
        print(out / name)
    print(json.dumps({"out": str(out), "screenshots": len(written), **timings}))


if __name__ == "__main__":
    main()
