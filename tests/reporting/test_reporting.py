"""Session reports: files written and valid, the seed's tables' numbers in them, figures with content,
hostile strings escaped, failed and partial sessions reported as such."""

from __future__ import annotations

import base64
import re
import threading
import xml.etree.ElementTree as ET
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from station.reporting import ReportError, ReportFiles, text_tables, write_report
from station.reporting._figure import magnification, nice_floor
from tests.reporting.reporting_sessions import session

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SVG_NS = "{http://www.w3.org/2000/svg}"
HOSTILE = '<script>alert("x")</script>'


@pytest.fixture(scope="module")
def reports(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[dict[str, Any], ReportFiles]]:
    """One report of each kind, written once for the module (figures cost a fraction of a second)."""
    out: dict[str, tuple[dict[str, Any], ReportFiles]] = {}
    for kind in ("validation", "repeatability", "sweep", "reanalyse"):
        s = session(kind, f"s-{kind}")
        out[kind] = (s, write_report(s, tmp_path_factory.mktemp(kind)))
    return out


class _Tags(HTMLParser):
    """Every start tag of a page with its attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def tags_of(page: str) -> list[tuple[str, dict[str, str | None]]]:
    p = _Tags()
    p.feed(page)
    return p.tags


def embedded_svgs(page: str) -> list[ET.Element]:
    """The figures embedded in a page, parsed as SVG documents."""
    data = re.findall(r'src="data:image/svg\+xml;base64,([A-Za-z0-9+/=]+)"', page)
    return [ET.fromstring(base64.b64decode(d)) for d in data]


def check_files(files: ReportFiles, names: list[str]) -> None:
    assert [p.name for p in files.figures] == [f"{n}.{ext}" for n in names for ext in ("png", "svg")]
    for p in files.figures:
        data = p.read_bytes()
        if p.suffix == ".png":
            assert data.startswith(PNG_MAGIC), p
        else:
            assert ET.fromstring(data).tag == f"{SVG_NS}svg", p
    assert not list(files.html.parent.glob(".*.tmp"))  # atomic writes leave no temporary file


def not_blank(png: Path) -> np.ndarray:
    image = cv2.imread(str(png), cv2.IMREAD_COLOR)
    assert image is not None
    assert image.shape[0] > 300
    assert image.shape[1] > 300
    non_white = (image < 240).any(axis=2).mean()
    assert non_white > 0.02, f"{png.name} is nearly blank ({non_white:.1%} drawn)"
    return image


def count_colour(image: np.ndarray, rgb: tuple[int, int, int], tol: int = 30) -> int:
    bgr = np.array(rgb[::-1], dtype=np.int16)
    return int((np.abs(image.astype(np.int16) - bgr).max(axis=2) <= tol).sum())


def test_validation_report_has_the_error_table_and_both_figures(reports: Any) -> None:
    s, files = reports["validation"]
    r = s["results"]
    check_files(files, ["validation-raw", "validation-parallelogram"])
    page = files.html.read_text(encoding="utf-8")
    for fit in ("rigid", "similarity", "affine"):
        assert f"<td>{r[fit]['mean_um']:.4f}</td><td>{r[fit]['max_um']:.4f}</td>" in page
    assert f"{r['groove_width_mm']:.5f} mm" in page
    assert "s-validation" in page
    assert "2026-11-27 18:30:05 UTC" in page
    assert "software 0.1.0" in page
    assert "CRS A465 / C500C" in page
    assert "<td>plan.approach_um</td><td>10.0</td>" in page
    assert "<td>measure.camera_matrix</td><td>-</td>" in page
    text = files.tables["validation"].splitlines()
    raw = next(line for line in text if line.startswith("raw (rigid)")).split()
    assert raw[2:4] == [f"{r['rigid']['mean_um']:.4f}", f"{r['rigid']['max_um']:.4f}"]
    assert len(files.tables["positions"].splitlines()) == 3 + 40 + 1  # title, header, rule, rows, note
    svgs = embedded_svgs(page)
    assert len(svgs) == 2
    assert all(svg.tag == f"{SVG_NS}svg" for svg in svgs)


def test_validation_figure_draws_magnified_error_lines(reports: Any) -> None:
    _, files = reports["validation"]
    image = not_blank(files.figures[0])
    assert count_colour(image, (214, 39, 40)) > 500  # the red error lines and measured points
    svg = files.figures[1].read_text(encoding="utf-8")
    title = re.search(r"<!-- (Raw: .*?) -->", svg)
    assert title is not None
    assert re.search(r"error lines ×(\d+)", svg), "the magnification is stated on the figure"


def test_repeatability_report_has_table_2_and_the_rp_circles(reports: Any) -> None:
    s, files = reports["repeatability"]
    r = s["results"]
    check_files(files, ["repeatability-joints", "repeatability-sequences", "repeatability-rp"])
    page = files.html.read_text(encoding="utf-8")
    text = files.tables["repeatability"]
    for name, t in r["tests"].items():
        cells = [f"{t[k]:.5f}" for k in ("l_bar_mm", "s_l_mm", "rp_mm")]
        lo, hi = t["rp_ci95_mm"]
        row = next(line for line in text.splitlines() if line.startswith(name + " "))
        assert cells[0] in row
        assert cells[2] in row
        assert f"{lo:.5f} - {hi:.5f}" in row
        assert row.split()[-2:] == ["30", f"{r['seed_table2_mm'][name]:.5f}"]
        assert "".join(f"<td>{c}</td>" for c in cells) in page
    for png in files.figures[::2]:
        not_blank(png)


def _x_extent(group: ET.Element) -> float:
    path = group.find(f"{SVG_NS}path")
    assert path is not None
    numbers = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?", path.attrib["d"])]
    xs = numbers[0::2]
    return max(xs) - min(xs)


def test_rp_circle_radius_matches_rp(reports: Any) -> None:
    s, files = reports["repeatability"]
    svg = ET.parse(files.figures[1]).getroot()
    groups = {g.attrib["id"]: g for g in svg.iter(f"{SVG_NS}g") if "id" in g.attrib}
    for name in ("J1", "J5"):
        t = s["results"]["tests"][name]
        rp = _x_extent(groups[f"rp-circle-{name}"])
        assert rp / _x_extent(groups[f"lbar-circle-{name}"]) == pytest.approx(
            t["rp_mm"] / t["l_bar_mm"], rel=0.01
        )
        assert rp / _x_extent(groups[f"rp-interval-{name}"]) == pytest.approx(
            t["rp_mm"] / t["rp_ci95_mm"][1], rel=0.01
        )
    # all joint panels share one scale: J5's circle is drawn larger than J1's by RP's ratio
    j1, j5 = (s["results"]["tests"][n]["rp_mm"] for n in ("J1", "J5"))
    ratio = _x_extent(groups["rp-circle-J5"]) / _x_extent(groups["rp-circle-J1"])
    assert ratio == pytest.approx(j5 / j1, rel=0.01)


def test_sweep_report_is_table_1_with_the_best_trial_marked(reports: Any) -> None:
    s, files = reports["sweep"]
    r = s["results"]
    check_files(files, ["sweep"])
    not_blank(files.figures[0])
    rows = files.tables["sweep"].splitlines()
    assert rows[1].split() == ["Trial", "Filter", "SK", "TW", "TH", "MaxE", "MeanE", "best"]
    best = next(t for t in r["trials"] if t["number"] == r["best"])
    best_row = next(line.split() for line in rows[3:12] if line.split()[0] == str(r["best"]))
    assert best_row[5:] == [f"{best['max_um'] / 1000:.5f}", f"{best['mean_um'] / 1000:.5f}", "*"]
    failed = next(line for line in rows if line.startswith("6 "))
    assert "failed" in failed
    assert "only 3 of 4 edges found" in failed
    assert "seed_table_1" in files.tables
    assert "0.0080" in files.tables["seed_table_1"]
    page = files.html.read_text(encoding="utf-8")
    assert f'<tr class="marked"><td>{r["best"]}</td>' in page
    assert page.count('class="marked"') == 1


def test_reanalyse_is_reported_as_its_source_kind(reports: Any) -> None:
    s, files = reports["reanalyse"]
    check_files(files, ["validation-raw", "validation-parallelogram"])
    page = files.html.read_text(encoding="utf-8")
    assert "<h1>Re-analysis (validation against the x-y table)</h1>" in page
    assert "<td>source session</td><td>v-1</td>" in page
    mean = s["results"]["validation"]["affine"]["mean_um"]
    assert f"<td>{mean:.4f}</td>" in page


def test_text_tables_are_the_reports_tables(reports: Any) -> None:
    for s, files in reports.values():
        assert text_tables(s) == files.tables
    assert list(reports["repeatability"][1].tables) == ["session", "devices", "parameters", "repeatability"]


def test_failed_session_without_results_says_so(tmp_path: Path) -> None:
    error = "camera timeout: no frame within 2.0 s; check the cable"
    s = session(
        "repeatability", "s-failed", state="failed", results=None, error={"message": error, "code": "E1"}
    )
    files = write_report(s, tmp_path)
    assert files.figures == ()
    page = files.html.read_text(encoding="utf-8")
    assert "did not succeed" in page
    assert "<b>failed</b>" in page
    assert f"{error} (E1)" in page
    assert "It has no results" in page
    assert list(files.tables) == ["session", "devices", "parameters"]
    assert f"error     {error} (E1)" in files.tables["session"]


def test_interrupted_session_keeps_partial_results(tmp_path: Path) -> None:
    s = session("repeatability", "s-part", state="interrupted")
    r = s["results"]
    r["tests"] = {"J1": r["tests"]["J1"]}  # interrupted after the first test
    r["rp_mm"] = {"J1": r["rp_mm"]["J1"]}
    files = write_report(s, tmp_path)
    check_files(files, ["repeatability-joints", "repeatability-rp"])
    page = files.html.read_text(encoding="utf-8")
    assert "station run --resume s-part" in page
    assert "results below are partial" in page
    assert f"{r['rp_mm']['J1']:.5f}" in files.tables["repeatability"]


def test_unreadable_partial_results_are_shown_as_recorded(tmp_path: Path) -> None:
    s = session("validation", "s-odd", state="aborted", results={"positions": [{"index": 0}], "note": "<b>"})
    files = write_report(s, tmp_path)
    page = files.html.read_text(encoding="utf-8")
    assert "results.mean_um: Field required" in page
    assert "<h2>Results as recorded</h2><pre>" in page
    assert "&quot;note&quot;: &quot;&lt;b&gt;&quot;" in page


def test_hostile_strings_are_escaped(tmp_path: Path) -> None:
    s = session(
        "sweep",
        HOSTILE,
        state="failed",
        error=HOSTILE,
        params={HOSTILE: HOSTILE, "mode": "<i>paper</i>"},
        identities={"robot": {"model": '<img src=x onerror="alert(1)">'}},
        software={"version": HOSTILE},
    )
    s["results"]["trials"][0]["error"] = HOSTILE
    s["results"]["trials"][1]["overrides"] = {HOSTILE: 1}
    page = write_report(s, tmp_path).html.read_text(encoding="utf-8")
    tags = tags_of(page)
    assert not [t for t, _ in tags if t in ("script", "i")]
    assert not [a for t, a in tags if t == "img" and "onerror" in a]
    assert "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;" in page
    assert "<title>Session &lt;script&gt;" in page


def test_succeeded_session_with_malformed_results_is_refused(tmp_path: Path) -> None:
    s = session("validation")
    del s["results"]["positions"][3]["measured_um"]
    with pytest.raises(ReportError, match=r"results\.positions\.3\.measured_um: Field required"):
        write_report(s, tmp_path)
    assert not (tmp_path / "report.html").exists()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"id": None}, "lacks 'id'"),
        ({"kind": "hand-eye"}, "unknown kind 'hand-eye'"),
        ({"results": [1, 2]}, "results must be an object"),
    ],
)
def test_rejects_what_is_not_a_session(change: dict[str, Any], message: str) -> None:
    with pytest.raises(ReportError, match=message):
        text_tables(session("sweep") | change)


def test_reanalyse_needs_its_source_kind() -> None:
    s = session("reanalyse", results={"source_session": "v-1"})
    with pytest.raises(ReportError, match="must name the source's kind"):
        text_tables(s)


def test_unwritable_folder_is_a_report_error(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(ReportError, match="cannot create the report folder"):
        write_report(session("sweep", results=None, state="failed"), blocker / "report")


@pytest.mark.parametrize(
    ("x", "expected"), [(1.0, 1.0), (4.99, 2.0), (5.0, 5.0), (73.0, 50.0), (0.031, 0.02)]
)
def test_nice_floor(x: float, expected: float) -> None:
    assert nice_floor(x) == pytest.approx(expected)


def test_magnification_draws_the_largest_error_near_a_seventh_of_the_pattern() -> None:
    assert magnification(50.8, 0.16) == 20.0  # 0.15 * 50.8 / 0.16 = 47.6 -> 20
    assert magnification(50.8, 30.0) == 1.0  # never shrinks errors
    assert magnification(50.8, 0.0) == 1.0


def test_sweep_over_any_grid_and_with_every_trial_failed(tmp_path: Path) -> None:
    trials = [
        {"number": i + 1, "overrides": {"TESTWIDTH": w}, "mean_um": None, "max_um": None, "error": f"bad {w}"}
        for i, w in enumerate((3, 5, 7))
    ]
    s = session("sweep", results={"trials": trials, "best": None, "source_session": "v-1"})
    files = write_report(s, tmp_path)  # no best, no numbers: still a report, and no warning (errors here)
    rows = files.tables["sweep"].splitlines()
    assert rows[1].split() == ["Trial", "TESTWIDTH", "MaxE", "MeanE", "best"]
    assert rows[3].split() == ["1", "3", "failed", "bad", "3"]
    assert "seed_table_1" not in files.tables
    assert 'class="marked"' not in files.html.read_text(encoding="utf-8")


def test_reanalysed_repeatability_and_scale_calibration_origin() -> None:
    rep = session("repeatability")["results"]
    rep["tests"] = {}  # a re-analysis that kept only the RP per test
    s = session(
        "reanalyse", "s-re", results={"source_session": "r-9", "kind": "repeatability", "repeatability": rep}
    )
    tables = text_tables(s)
    assert "source session  r-9" in tables["session"]
    assert f"{rep['rp_mm']['J5']:.5f}" in tables["repeatability"]
    v = session("validation", "v-1")  # the synthetic scale calibration names session v-1
    assert "(estimated by this session)" in text_tables(v)["validation"]
    assert "(from session v-1)" in text_tables(session("validation", "v-2"))["validation"]


def test_failed_tests_and_unmeasured_captures_are_listed(tmp_path: Path) -> None:
    s = session("repeatability", "s-fail-some")
    r = s["results"]
    r["tests"] = {
        "J1": r["tests"]["J1"],
        "J2": {"error": "only 2 cycle captures were measured; RP needs at least 3"},
    }
    r["rp_mm"] = {"J1": r["rp_mm"]["J1"]}
    r["tests"]["J1"]["failures"] = [
        {"capture_id": 17, "step_index": 4, "frame_index": 0, "error": "no cross found", "code": "no_cross"}
    ]
    files = write_report(s, tmp_path)
    check_files(files, ["repeatability-joints", "repeatability-rp"])
    j2 = next(line for line in files.tables["repeatability"].splitlines() if line.startswith("J2 "))
    assert "no RP: only 2 cycle captures were measured" in j2
    assert files.tables["failures"].splitlines()[3].split() == [
        "J1",
        "4",
        "0",
        "17",
        "no",
        "cross",
        "found",
        "(no_cross)",
    ]


def test_sweep_prefers_the_parallelogram_errors_of_table_1() -> None:
    s = session("sweep")
    assert "after the rigid fit" in text_tables(s)["sweep"]  # trials with mean_um / max_um only
    for t in s["results"]["trials"]:
        if t["mean_um"] is not None:
            t.update(parallelogram_mean_um=t["mean_um"] / 2, parallelogram_max_um=t["max_um"] / 2)
    table = text_tables(s)["sweep"]
    assert "after the well-fit parallelogram" in table
    first = s["results"]["trials"][0]
    assert f"{first['parallelogram_max_um'] / 1000:.5f}  {first['parallelogram_mean_um'] / 1000:.5f}" in table


def test_repeatability_with_z_adds_the_3d_columns() -> None:
    s = session("repeatability", "s-z")
    tests = s["results"]["tests"]
    first, second = list(tests)[:2]
    tests[first].update(
        {"rp3d_mm": 0.031234, "l_bar3d_mm": 0.02, "s_l3d_mm": 0.004, "rp3d_ci95_mm": [0.025, 0.04]}
    )
    tests[second]["rp3d_error"] = "no z on 1 of 30 cycle captures: out of range"
    text = text_tables(s)["repeatability"]
    header = next(line for line in text.splitlines() if line.startswith("test "))
    assert header.split()[-2:] == ["RP3D_mm", "RP3D_95%_mm"]
    row = next(line for line in text.splitlines() if line.startswith(first + " "))
    assert "0.03123" in row
    assert "0.02500 - 0.04000" in row
    assert "no RP3D: no z on 1 of 30" in next(
        line for line in text.splitlines() if line.startswith(second + " ")
    )
    assert "z from the distance sensor" in text
    # without z the table is as before
    plain = text_tables(session("repeatability", "s-plain"))["repeatability"]
    assert "RP3D" not in plain


def test_concurrent_writes_of_one_report_file_never_collide(tmp_path: Path) -> None:
    """Writers of the same report at once (threads here; the service and ``station report`` in two
    processes alike) each write a temporary file of their own: none fails, a reader only ever sees a
    whole file, and no temporary file is left. With one fixed temporary name, a writer renamed another's
    half-written file away and the other failed ("No such file or directory")."""
    from station.reporting._write import _write_atomic

    target = tmp_path / "report.html"
    payloads = [bytes([65 + k]) * 300_000 for k in range(4)]
    errors: list[str] = []
    seen: list[bytes] = []
    writing = threading.Event()

    def writer(k: int) -> None:
        for _ in range(50):
            try:
                _write_atomic(target, payloads[k])
            except ReportError as exc:
                errors.append(str(exc))
            writing.set()

    def reader() -> None:
        writing.wait(30)
        while True:  # at least once, then as long as any writer writes
            seen.append(target.read_bytes())
            if not any(t.is_alive() for t in writers):
                return

    writers = [threading.Thread(target=writer, args=(k,)) for k in range(4)]
    watcher = threading.Thread(target=reader)
    for t in [*writers, watcher]:
        t.start()
    for t in [*writers, watcher]:
        t.join(60)
    assert errors == []
    assert seen
    assert all(s in payloads for s in seen)  # never half a file
    assert target.read_bytes() in payloads
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.html"]  # no temporary file left
