"""Calibration reports (issue 11, item 5) from a real session's results: the relative error before / after /
floor with the targets' ratios, residuals, per-parameter estimates with 95 % intervals, the identifiability
table with the structural list, and the three figures.

The fixture ``tests/data/calibration_session.json`` is a small simulated session's record document
(``station run calibration --sim --param 'turns_deg=[-20,160]'``, 32 configurations, 5 placements), as
``station report`` reads it; only the CalibrationResult's copy of the parameter list was removed.
"""

from __future__ import annotations

import io
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
from matplotlib.figure import Figure

from station.cli import main
from station.kinds.calibration.report_figures import (
    calibration_parameters_figure,
    calibration_residuals_figure,
)
from station.kinds.calibration.results import CalibrationResults
from station.record import Record
from station.reporting import ReportError, ReportFiles, text_tables, write_report
from station.reporting._model import parse_session
from tests.reporting.test_reporting import SVG_NS, check_files, embedded_svgs, not_blank

FIXTURE = Path(__file__).parents[1] / "data" / "calibration_session.json"
FIGURES = ["calibration-residuals", "calibration-parameters", "calibration-singular-values"]


def calibration_session() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(FIXTURE.read_text(encoding="utf-8"))
    return doc


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict[str, Any], ReportFiles]:
    s = calibration_session()
    return s, write_report(s, tmp_path_factory.mktemp("calibration"))


def svg_of(figure: Figure) -> ET.Element:
    buf = io.BytesIO()
    figure.savefig(buf, format="svg")
    return ET.fromstring(buf.getvalue())


def is_dh(p: dict[str, Any]) -> bool:
    return not p["name"].startswith(("tool", "artifact"))


def rows_of(text: str) -> dict[str, list[str]]:
    """A text table's rows by their first cell (cells split on runs of two or more spaces)."""
    out = {}
    for line in text.splitlines()[3:]:
        cells = re.split(r"\s{2,}", line.strip())
        if len(cells) > 1:
            out[cells[0]] = cells[1:]
    return out


def test_the_fixture_is_a_real_calibrations_results() -> None:
    r = calibration_session()["results"]
    assert r["relative_error_um"]["before"] > 10 * r["relative_error_um"]["after"]
    assert r["identified_count"] == sum(p["identified"] for p in r["parameters"])
    assert r["unidentifiable"] == [d["name"] for d in r["calibration"]["identifiability"]["structural"]]


def test_relative_error_table_gives_before_after_floor_and_the_targets(report: Any) -> None:
    s, files = report
    e = s["results"]["relative_error_um"]
    rows = rows_of(files.tables["relative_error"])
    assert rows["before (nominal model)"] == [f"{e['before']:.1f}"]
    assert rows["after (calibrated model)"] == [f"{e['after']:.1f}"]
    assert rows["floor (repeatability and noise)"] == [f"{e['floor']:.1f}"]
    gain, excess = e["before"] / e["after"], e["after"] / e["floor"]
    assert rows["before / after"] == [f"{gain:.1f}x", ">= 10x: " + ("met" if gain >= 10 else "NOT met")]
    assert rows["after / floor"] == [f"{excess:.2f}x", "<= 2x: " + ("met" if excess <= 2 else "NOT met")]
    # this small session (two turns) leaves the after at 3.1x the floor: the report says so
    assert rows["after / floor"][1] == "<= 2x: NOT met"
    held = ", ".join(map(str, s["results"]["held_out_configurations"]))
    assert f"held-out configurations: {held}" in files.tables["relative_error"]
    assert s["results"]["floor_source"] in files.tables["relative_error"]


def test_residuals_table_before_and_after_on_fitted_and_held_out(report: Any) -> None:
    s, files = report
    cal = s["results"]["calibration"]
    lines = files.tables["residuals"].splitlines()
    sets = [
        ("fitted", cal["residuals"]["before"], cal["residuals"]["after"]),
        ("held out", cal["cross_validation"]["before"], cal["cross_validation"]["after"]),
    ]
    for data, before, after in sets:
        for model, r in (("before", before), ("after", after)):
            row = next(line for line in lines if re.match(rf"{data}\s+{model}\s", line))
            cells = row.split()[len(data.split()) + 1 :]
            expected = [f"{r[k] * 1000:.2f}" for k in ("rms_xy_mm", "max_xy_mm", "rms_z_mm", "max_z_mm")]
            assert cells[:5] == [str(r["n"]), *expected]
        gain = before["rms_xy_mm"] / after["rms_xy_mm"]
        assert gain > 10
        assert re.search(rf"{data}\s+after\s.*\s{gain:.1f}x$", files.tables["residuals"], re.M)
    fit = cal["fit"]
    assert f"{fit['dof']} degrees of freedom" in files.tables["residuals"]


def test_every_parameter_with_its_estimate_interval_and_status(report: Any) -> None:
    s, files = report
    r = s["results"]
    rows = rows_of(files.tables["estimates"])
    assert len(rows) == len(r["parameters"])
    reasons = {d["name"]: d["reason"] for d in r["calibration"]["identifiability"]["structural"]}
    reasons["d3"] = reasons["d2-d3"]  # the pair's difference stands for d3, which stays nominal
    for p in r["parameters"]:
        digits = 5 if p["unit"] == "deg" else 4
        cells = rows[p["name"]]
        assert cells[1:4] == [
            p["unit"],
            f"{p['nominal']:.{digits}f}",
            f"{p['estimate'] - p['nominal']:+.{digits}f}",
        ]
        if p["structural"]:
            assert cells[4:6] == ["-", "-"]
            assert cells[6] == f"not identifiable (structural): {reasons[p['name']]}"
        else:
            lo, hi = (v - p["nominal"] for v in p["interval"])
            assert cells[4:] == [
                f"{lo:+.{digits}f} .. {hi:+.{digits}f}",
                f"{p['sigma']:.{digits}f}",
                "identified",
            ]
    assert [c[0] for c in rows.values()][:25] == ["DH"] * 25  # grouped: DH, tool, artifacts
    assert rows["tool_rz"][0] == "tool"
    assert rows["artifact4_ry"][0] == "artifacts"
    assert "d2+d3" in rows
    assert f"{r['identified_count']} identified of {len(r['parameters'])}" in files.tables["estimates"]


def test_identifiability_table_and_the_structural_list(report: Any) -> None:
    s, files = report
    r = s["results"]
    i = r["calibration"]["identifiability"]
    rows = rows_of(files.tables["identifiability"])
    assert rows["condition number (identified set, unit columns)"] == [f"{r['condition_number']:.4g}"]
    assert rows["identified parameters"] == [f"{r['identified_count']} of {len(r['parameters'])}"]
    assert rows["null dimension (all parameters)"] == [str(i["null_dimension"])]
    assert rows["structural list verified"] == ["yes"]
    sv = i["singular_values"]
    assert (
        f"{len(sv)} values, largest {max(sv):.3g}, smallest {min(sv):.3g}"
        in rows["singular values (scaled Jacobian)"][0]
    )
    below = sum(v < i["rcond"] * max(sv) for v in sv)
    assert below == i["null_dimension"] == 7
    assert f"; {below} below rcond" in rows["singular values (scaled Jacobian)"][0]
    assert rows["deficient in this pose set"] == ["none"]
    assert "deficiencies" not in files.tables  # the rich pose set leaves nothing undetermined

    structural = rows_of(files.tables["structural"])
    assert list(structural) == r["unidentifiable"]
    assert set(structural) == {"alpha0", "a0", "d1", "theta1_offset", "d2-d3", "d6", "theta6_offset"}
    # what each trades with, as the identification found it
    assert structural["d6"][0] == "+1 tool_z"
    assert structural["theta6_offset"][0] == "+1 tool_rz"
    assert structural["d2-d3"][0] == "+1 d2"
    assert structural["d1"][0].startswith("-1 artifact")
    assert structural["d1"][0].count("_z") == 5
    assert structural["alpha0"][0].endswith("(+3 more)")  # eight artifact terms, the five largest shown
    for d in i["structural"]:
        assert structural[d["name"]][-1] == d["reason"]


def test_figures_are_written_with_their_content(report: Any) -> None:
    s, files = report
    r = s["results"]
    check_files(files, FIGURES)
    for png in files.figures[::2]:
        not_blank(png)
    svgs = {p.stem: p.read_text(encoding="utf-8") for p in files.figures[1::2]}

    # residuals: before / after bars, rms/max xy/z, fitted and held-out sets, and the relative error
    res = ET.fromstring(svgs["calibration-residuals"])
    gids = [g.attrib["id"] for g in res.iter(f"{SVG_NS}g") if "id" in g.attrib]
    assert sum(g.startswith("bar-before-") for g in gids) == 8 + 1
    assert sum(g.startswith("bar-after-") for g in gids) == 8 + 1
    assert "relative-error-floor" in gids
    e = r["relative_error_um"]
    assert f"floor {e['floor']:.3g} µm" in svgs["calibration-residuals"]
    assert f"<!-- {e['after']:.3g} -->" in svgs["calibration-residuals"]
    assert f"<!-- {e['before']:.0f} -->" in svgs["calibration-residuals"]

    # parameters: every parameter named, estimates drawn per (group, unit) panel
    par = svgs["calibration-parameters"]
    for p in r["parameters"]:
        assert f"<!-- {p['name']} -->" in par, p["name"]
    for panel in ("DH (mm)", "DH (deg)", "tool (mm)", "tool (deg)", "artifacts (mm)", "artifacts (deg)"):
        assert f"<!-- {panel} -->" in par
    assert f"{r['identified_count']} identified of {len(r['parameters'])}" in par

    # singular values: the rcond line and the count below it
    sv = svgs["calibration-singular-values"]
    assert 'id="rcond-line"' in sv
    assert "<!-- 7 below rcond -->" in sv
    assert f"<!-- {len(r['parameters']) - 7} above rcond -->" in sv


def test_singular_value_points_sit_on_either_side_of_the_rcond_line(report: Any) -> None:
    _, files = report
    svg = ET.parse(files.figures[5]).getroot()
    line = next(g for g in svg.iter(f"{SVG_NS}g") if g.attrib.get("id") == "rcond-line")
    path = line.find(f"{SVG_NS}path")
    assert path is not None
    y_line = float(re.findall(r"-?\d+(?:\.\d+)?", path.attrib["d"])[1])
    groups = {g.attrib["id"]: g for g in svg.iter(f"{SVG_NS}g") if "id" in g.attrib}
    # each point is a <use> of the marker; SVG y grows downwards
    above = [float(u.attrib["y"]) for u in groups["singular-values-above"].iter(f"{SVG_NS}use")]
    below = [float(u.attrib["y"]) for u in groups["singular-values-below"].iter(f"{SVG_NS}use")]
    assert len(above) == 49
    assert len(below) == 7
    assert max(above) < y_line < min(below)


def test_html_report_holds_the_tables_and_figures(report: Any) -> None:
    s, files = report
    page = files.html.read_text(encoding="utf-8")
    assert "<h1>Kinematic calibration</h1>" in page
    for caption in (
        "Relative positioning error",
        "Residuals before and after",
        "Parameter estimates",
        "Identifiability",
        "Not identifiable on this arm (structural)",
    ):
        assert f"<caption>{caption}</caption>" in page
    assert f"<td>{s['results']['relative_error_um']['after']:.1f}</td>" in page
    assert "<td>d2-d3</td><td>+1 d2</td>" in page
    assert "Keyence IL-065 via DL-RS1A" in page
    assert len(embedded_svgs(page)) == 3


def test_text_tables_are_the_reports(report: Any) -> None:
    s, files = report
    tables = text_tables(s)
    assert tables == files.tables
    assert list(tables) == [
        "session",
        "devices",
        "parameters",
        "relative_error",
        "residuals",
        "estimates",
        "identifiability",
        "structural",
    ]


def test_a_poor_pose_set_lists_what_it_does_not_determine() -> None:
    s = calibration_session()
    i = s["results"]["calibration"]["identifiability"]
    i["deficient"] = ["a2", "d4", "tool_z"]
    i["dropped"] = [
        {"name": "d4", "combination": {"a2": -0.98, "tool_z": 0.2}, "residual": 3.2e-7, "reason": ""}
    ]
    for p in s["results"]["parameters"]:
        if p["name"] == "d4":
            p.update(identified=False, sigma=None, interval=None, estimate=p["nominal"])
    tables = text_tables(s)
    rows = rows_of(tables["deficiencies"])
    assert rows["d4"][:2] == ["-0.98 a2 +0.2 tool_z", "3.2e-07"]
    assert rows["a2"] == ["(weight in a near-null direction)"]
    assert rows["tool_z"] == ["(weight in a near-null direction)"]
    assert "d4" not in [*rows_of(tables["structural"])]
    assert rows_of(tables["identifiability"])["deficient in this pose set"] == ["a2, d4, tool_z"]
    assert rows_of(tables["estimates"])["d4"][-1] == "not identified (this pose set)"
    parsed = parse_session(s).results
    assert isinstance(parsed, CalibrationResults)
    svg = svg_of(calibration_parameters_figure(parsed).figure)
    groups = {g.attrib["id"]: g for g in svg.iter(f"{SVG_NS}g") if "id" in g.attrib}
    dh_mm = groups["estimates-DH-mm"]  # d4 left the fitted points of its panel: one point fewer
    fitted = sum(1 for p in s["results"]["parameters"] if p["unit"] == "mm" and p["identified"] and is_dh(p))
    assert len(list(dh_mm.iter(f"{SVG_NS}use"))) == fitted


def test_missing_floor_and_cross_validation_are_stated() -> None:
    s = calibration_session()
    r = s["results"]
    r["relative_error_um"] = {"before": r["relative_error_um"]["before"], "after": 30.0, "floor": None}
    r["calibration"]["cross_validation"] = None
    r["held_out_configurations"] = []
    tables = text_tables(s)
    rows = rows_of(tables["relative_error"])
    assert rows["floor (repeatability and noise)"] == ["-"]
    assert rows["after / floor"] == ["-", "<= 2x: -"]
    assert "not computed: floor" in tables["relative_error"]
    assert "held-out configurations: none" in tables["relative_error"]
    assert not any(line.startswith("held out") for line in tables["residuals"].splitlines())
    parsed = parse_session(s).results
    assert isinstance(parsed, CalibrationResults)
    res = svg_of(calibration_residuals_figure(parsed).figure)
    gids = [g.attrib["id"] for g in res.iter(f"{SVG_NS}g") if "id" in g.attrib]
    assert sum(g.startswith("bar-after-") for g in gids) == 4 + 1
    assert "relative-error-floor" not in gids


def test_malformed_calibration_results_name_the_field(tmp_path: Path) -> None:
    s = calibration_session()
    del s["results"]["parameters"][4]["estimate"]
    with pytest.raises(ReportError, match=r"results\.parameters\.4\.estimate: Field required"):
        write_report(s, tmp_path)
    s = calibration_session()
    s["results"]["calibration"]["identifiability"]["singular_values"] = "many"
    with pytest.raises(ReportError, match=r"results\.calibration\.identifiability\.singular_values"):
        text_tables(s)
    assert not (tmp_path / "report.html").exists()


def test_a_reanalysed_calibration_is_reported_as_one() -> None:
    s = calibration_session()
    s.update(
        kind="reanalyse",
        results={"source_session": s["id"], "kind": "calibration", "calibration": s["results"]},
    )
    tables = text_tables(s)
    assert f"source session  {calibration_session()['id']}" in tables["session"]
    assert "structural" in tables


def test_station_report_prints_the_calibration_tables(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = calibration_session()
    data = tmp_path / "data"
    with Record(data) as record:
        row = record.create_session(
            "calibration", params=s["params"], config={}, identities=s["identities"], software=s["software"]
        )
        record.set_results(row.id, s["results"])
        record.set_state(row.id, "succeeded")
    assert main(["report", row.id, "--data", str(data), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    for title in (
        "Relative positioning error",
        "Parameter estimates",
        "Not identifiable on this arm (structural)",
    ):
        assert title in out
    assert f"{s['results']['relative_error_um']['before']:.1f}" in out
    for name in FIGURES:
        assert f"figure: {tmp_path / 'out' / name}.png" in out
