"""Ended sessions in the page (issue 20, rows 5, 6, 7 and part of 10), on one record prepared through the
API: a validation, a one-test repeatability, a session that failed at pre-flight, and a later
validation (so that the first is not the latest).

* row 5: the report served by the API loads its figure files (its links were relative and answered 404);
* row 6: a finished session other than the latest shows its real progress (it showed "0 / 0 steps");
* row 7: the figure of a ``joints=[1]`` repeatability is not cut off at its edges;
* row 10: past sessions are reachable by keyboard, the chosen one highlighted with the focus visible;
  figures open full size and the page stays readable at 800 px; a failed session's Results panel says
  what happened instead of staying empty.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from api import Access, ServiceSettings, StationService
from tests.api.conftest import TOKEN, Served, serve, wait_final
from tests.api.page.conftest import NARROW, PATTERN, Visit, api, open_page

FAR = {"S1": [[0, 30, 60, 0, 90, 0], [75, 30, 60, 0, 90, 0]]}  # beyond joint 1's limit: pre-flight fails


@dataclass
class Record:
    served: Served
    first: str
    repeatability: str
    failed: str
    latest: str


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Record]:
    data: Path = tmp_path_factory.mktemp("page") / "data"
    served = serve(StationService(ServiceSettings(sim=True, data=data)), Access(TOKEN, True))
    try:
        with api(served.base) as c:

            def run(kind: str, params: dict[str, Any]) -> str:
                sid: str = c.post("/api/v1/sessions", json={"kind": kind, "params": params}).json()["id"]
                assert wait_final(c, sid)["state"] == "succeeded"
                return sid

            first = run("validation", {"pattern_um": PATTERN})
            repeatability = run("repeatability", {"cycles": 5, "joints": [1], "warmup_cycles": 0})
            refused = c.post(
                "/api/v1/sessions", json={"kind": "repeatability", "params": {"joints": [], "sequences": FAR}}
            )
            assert refused.status_code == 422
            failed = c.get("/api/v1/sessions", params={"limit": 1}).json()["items"][0]["id"]
            latest = run("validation", {"pattern_um": PATTERN[:3]})
        yield Record(served, first, repeatability, failed, latest)
    finally:
        served.stop()


def choose(visit: Visit, sid: str) -> None:
    """Click the session's row in Past sessions and wait for the Session panel to show it."""
    visit.page.click(f"#sessions tr[data-id='{sid}'] .row-open")
    visit.page.wait_for_function("sid => document.querySelector('#session-id').textContent === sid", arg=sid)


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_finished_session_other_than_the_latest_shows_its_progress(recorded: Record, browser: Any) -> None:
    visit = open_page(browser, recorded.served.base)
    page = visit.page
    page.wait_for_selector(f"#sessions tr[data-id='{recorded.first}']")
    steps = page.text_content(f"#sessions tr[data-id='{recorded.first}'] td:nth-child(4)")
    assert steps == f"{len(PATTERN)} / {len(PATTERN)}"
    choose(visit, recorded.first)
    assert page.text_content("#progress-text") == f"{len(PATTERN)} / {len(PATTERN)} steps"
    assert (
        page.get_attribute("#progress", "value")
        == page.get_attribute("#progress", "max")
        == str(len(PATTERN))
    )
    with api(recorded.served.base) as c:
        progress = c.get(f"/api/v1/sessions/{recorded.first}").json()["progress"]
    assert progress == {"done": len(PATTERN), "total": len(PATTERN), "eta_s": None}
    assert visit.failed == []


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_the_served_report_loads_its_figure_files(recorded: Record, browser: Any) -> None:
    visit = open_page(browser, recorded.served.base)
    page = visit.page
    sid = recorded.repeatability
    link = f"#sessions tr[data-id='{sid}'] a:text-is('report')"
    page.wait_for_selector(link)
    with page.context.expect_page() as opened:
        page.click(link)
    report = opened.value
    report.wait_for_load_state()
    hrefs = report.eval_on_selector_all("figcaption a", "links => links.map(a => a.href)")
    assert any(h.endswith(".png") for h in hrefs)
    assert any(h.endswith(".svg") for h in hrefs)
    for href in hrefs:
        assert f"/api/v1/sessions/{sid}/figures/" in href
        response = report.goto(href)
        assert response is not None
        assert response.status == 200, href
    assert visit.failed == []
    assert visit.console_errors == []


# Whether a figure, drawn on a canvas in the page, has ink (a non-white pixel) on its outermost rows or
# columns: a title or legend cut off at the figure's edge leaves some there; a figure that fits, none.
INK_AT_EDGE = """async src => {
    const img = new Image();
    img.src = src;
    await img.decode();
    const c = document.createElement('canvas');
    c.width = img.naturalWidth; c.height = img.naturalHeight;
    const g = c.getContext('2d');
    g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const inked = (x, y) => {
        const i = 4 * (y * c.width + x);
        return d[i] < 200 || d[i + 1] < 200 || d[i + 2] < 200;
    };
    const edges = {top: 0, bottom: 0, left: 0, right: 0};
    for (let x = 0; x < c.width; x++) { edges.top += inked(x, 0); edges.bottom += inked(x, c.height - 1); }
    for (let y = 0; y < c.height; y++) { edges.left += inked(0, y); edges.right += inked(c.width - 1, y); }
    return edges;
}"""


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_one_test_repeatability_figure_is_not_cut_off(recorded: Record, browser: Any) -> None:
    visit = open_page(browser, recorded.served.base)
    page = visit.page
    page.wait_for_selector(f"#sessions tr[data-id='{recorded.repeatability}']")
    choose(visit, recorded.repeatability)
    page.wait_for_selector("#figures img[alt='figure repeatability-joints.png']")
    src = page.get_attribute("#figures img[alt='figure repeatability-joints.png']", "src")
    edges = page.evaluate(INK_AT_EDGE, src)
    assert edges == {"top": 0, "bottom": 0, "left": 0, "right": 0}, edges


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_past_sessions_are_reachable_by_keyboard_and_the_choice_is_highlighted(
    recorded: Record, browser: Any
) -> None:
    visit = open_page(browser, recorded.served.base)
    page = visit.page
    page.wait_for_selector(f"#sessions tr[data-id='{recorded.first}']")
    target = f"#sessions tr[data-id='{recorded.first}']"
    # Tab through the page until the first validation's row has the focus (a keyboard user's way there)
    for _ in range(200):
        page.keyboard.press("Tab")
        if page.evaluate("t => document.activeElement.closest(t) !== null", target):
            break
    else:
        raise AssertionError("no control of the session's row is reachable with Tab")
    outline = page.evaluate("getComputedStyle(document.activeElement).outlineStyle")
    assert outline != "none"  # the focus is visible
    page.keyboard.press("Enter")
    page.wait_for_function(
        "sid => document.querySelector('#session-id').textContent === sid", arg=recorded.first
    )
    assert page.get_attribute(target, "aria-current") == "true"
    assert "selected" in (page.get_attribute(target, "class") or "")
    others = page.eval_on_selector_all("#sessions tr[aria-current='true']", "rows => rows.length")
    assert others == 1
    # the panel that changed is in view, and the chosen row still has the focus
    top = page.evaluate("document.querySelector('#session-section').getBoundingClientRect().top")
    assert 0 <= top < page.viewport_size["height"]
    assert page.evaluate("t => document.activeElement.closest(t) !== null", target)


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_figures_open_full_size_and_the_page_is_readable_at_800_px(recorded: Record, browser: Any) -> None:
    visit = open_page(browser, recorded.served.base, viewport=NARROW)
    page = visit.page
    page.wait_for_selector(f"#sessions tr[data-id='{recorded.first}']")
    choose(visit, recorded.first)
    page.wait_for_function(
        "document.querySelectorAll('#figures img').length > 0 && "
        "[...document.querySelectorAll('#figures img')].every(i => i.complete && i.naturalWidth > 0)"
    )
    # nothing wider than the window: figures scale, tables scroll inside their own box
    assert page.evaluate("document.documentElement.scrollWidth") <= NARROW["width"]
    widths = page.eval_on_selector_all(
        "#figures img", "imgs => imgs.map(i => i.getBoundingClientRect().width)"
    )
    assert all(w >= 0.8 * (NARROW["width"] - 60) for w in widths), (
        widths
    )  # one figure per row, near full width
    box = page.eval_on_selector("#positions-table", "t => getComputedStyle(t.parentElement).overflowX")
    assert box == "auto"
    # a figure opens full size on click
    page.click("#figures button.figure >> nth=0")
    page.wait_for_function("document.querySelector('#figure-dialog').open")
    page.wait_for_function("document.querySelector('#figure-full').complete")
    natural, shown = page.evaluate(
        "[document.querySelector('#figure-full').naturalWidth, document.querySelector('#figure-full').width]"
    )
    assert natural == shown > widths[0]
    page.keyboard.press("Escape")
    page.wait_for_function("!document.querySelector('#figure-dialog').open")
    assert visit.failed == []


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_failed_session_has_a_results_panel(recorded: Record, browser: Any) -> None:
    visit = open_page(browser, recorded.served.base)
    page = visit.page
    page.wait_for_selector(f"#sessions tr[data-id='{recorded.failed}']")
    choose(visit, recorded.failed)
    page.wait_for_selector("#results-state")
    text = " ".join((page.inner_text("#results-section") or "").split())
    assert f"Session {recorded.failed} failed" in text
    assert "pre-flight" in text
    # what it has (the test it could not compute, and why) instead of an empty panel
    assert "Its results below are partial" in text
    assert "not computed" in (page.text_content("#tests-table") or "")
    assert "RP needs at least 3" in (page.text_content("#tests-table") or "")
    assert re.search(r"HTML report", text)
    assert page.is_enabled("#resume")
    assert visit.failed == []
    assert visit.console_errors == []
