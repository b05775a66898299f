"""``station run`` / ``sessions`` / ``report`` / ``export`` / ``import`` as a user runs them: real
processes on the simulated station, a real SIGKILL between steps, and the resume."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from station.record import Record

STATION = [sys.executable, "-m", "station.cli"]


def station(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*STATION, *args], capture_output=True, text=True, timeout=timeout, check=False)


def last_json(out: str) -> Any:
    return json.loads(out.strip().splitlines()[-1])


def test_run_repeatability_prints_the_contract_object(tmp_path: Path) -> None:
    data = tmp_path / "data"
    p = station(
        "run",
        "repeatability",
        "--sim",
        "--param",
        "cycles=3",
        "--param",
        "warmup_cycles=0",
        "--param",
        "joints=[1, 6]",
        "--data",
        str(data),
        "--json",
    )
    assert p.returncode == 0, p.stderr
    doc = last_json(p.stdout)
    assert set(doc) >= {"id", "kind", "state", "results"}
    assert doc["kind"] == "repeatability"
    assert doc["state"] == "succeeded"
    assert set(doc["results"]["rp_mm"]) == {"J1", "J6"}
    assert doc["results"]["n_cycles"] == 3
    listed = station("sessions", "--json", "--data", str(data))
    assert listed.returncode == 0, listed.stderr
    sessions = json.loads(listed.stdout)
    assert [s["id"] for s in sessions] == [doc["id"]]
    assert sessions[0]["state"] == "succeeded"


def test_run_validation_json_keys_and_report_export_import(tmp_path: Path) -> None:
    data = tmp_path / "data"
    p = station("run", "validation", "--sim", "--param", "steps_per_side=2", "--data", str(data), "--json")
    assert p.returncode == 0, p.stderr
    doc = last_json(p.stdout)
    res = doc["results"]
    for key in (
        "mean_um",
        "max_um",
        "parallelogram_mean_um",
        "parallelogram_max_um",
        "scale",
        "groove_width_mm",
    ):
        assert isinstance(res[key], float), key
    for fit in ("rigid", "similarity", "affine"):
        assert set(res[fit]) == {"mean_um", "max_um", "rms_um", "scale"}
    assert (data / "scale-calibration.json").exists()  # the station's scale calibration, from this session

    rep = station("report", doc["id"], "--data", str(data))
    assert rep.returncode == 0, rep.stderr
    html = Path(rep.stdout.split("report: ")[1].splitlines()[0])
    assert html.exists()
    assert doc["id"] in html.read_text(encoding="utf-8")

    out = tmp_path / "export"
    ex = station("export", doc["id"], str(out), "--data", str(data))
    assert ex.returncode == 0, ex.stderr
    other = tmp_path / "other"
    folder = ex.stdout.strip()  # the folder written (inside OUT)
    assert Path(folder).is_relative_to(out)
    im = station("import", folder, "--data", str(other))
    assert im.returncode == 0, im.stderr
    assert im.stdout.strip() == doc["id"]
    with Record(data) as a, Record(other) as b:
        assert a.get_session(doc["id"]) == b.get_session(doc["id"])
        ca, cb = a.captures(doc["id"]), b.captures(doc["id"])
        assert [c.sha256 for c in ca] == [c.sha256 for c in cb]
        assert [m.result for m in a.measurements(doc["id"])] == [m.result for m in b.measurements(doc["id"])]


def test_reanalyse_reproduces_the_results_bit_for_bit(tmp_path: Path) -> None:
    data = tmp_path / "data"
    p = station("run", "validation", "--sim", "--param", "steps_per_side=2", "--data", str(data), "--json")
    assert p.returncode == 0, p.stderr
    original = last_json(p.stdout)
    again = station(
        "run",
        "reanalyse",
        "--param",
        f"session={original['id']}",
        "--data",
        str(data),
        "--json",
        "--jobs",
        "2",
    )
    assert again.returncode == 0, again.stderr
    doc = last_json(again.stdout)
    assert doc["results"]["source_session"] == original["id"]
    redone = doc["results"]["validation"]
    before = dict(original["results"])
    # the only differences: which session the scale estimate came from, and the controller's self-test,
    # which the session that drove the arm carries (station.selftest_status), not an analysis of its images
    assert redone.pop("scale_calibration")["session_id"] == original["id"]
    before.pop("scale_calibration")
    before.pop("selftest")
    before["checks"] = [c for c in before["checks"] if c["name"] != "selftest"]
    assert redone == before


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["run"], "give a session kind"),
        (["run", "repeatability", "--sim", "--param", "cycles=0"], "cycles"),
        (["run", "repeatability", "--sim", "--param", "speed_pct=101"], "speed_pct"),
        (["run", "repeatability"], "--sim or --config"),
        (["run", "validation", "--sim", "--param", "nonsense"], "NAME=VALUE"),
        (["run", "repeatability", "--config", "/nonexistent/station.toml"], "no such configuration file"),
    ],
)
def test_usage_errors_exit_2_with_one_clear_line(
    tmp_path: Path, args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """In-process (the same entry point as the console script): nothing is built, nothing moves."""
    from station.cli import main

    try:
        code = main([*args, "--data", str(tmp_path / "data")])
    except SystemExit as exc:  # argparse's own usage errors
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code == 2, err
    assert message in err
    assert "Traceback" not in err


def test_a_killed_session_is_interrupted_and_resumes(tmp_path: Path) -> None:
    """SIGKILL between two steps (a real subprocess): the record stays consistent, the unfinished
    session shows `interrupted`, and `station run --resume ID` completes it."""
    data = tmp_path / "data"
    proc = subprocess.Popen(
        [
            *STATION,
            "run",
            "repeatability",
            "--sim",
            "--param",
            "cycles=12",
            "--param",
            "warmup_cycles=0",
            "--param",
            "joints=[2]",
            "--data",
            str(data),
            "--json",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 120
        sid = None
        while time.monotonic() < deadline:
            if (data / "record.sqlite").exists():
                with Record(data) as rec:
                    rows = rec.list_sessions()
                    if rows and sum(s.state == "done" for s in rec.steps(rows[0].id)) >= 4:
                        sid = rows[0].id
                        break
            time.sleep(0.05)
        assert sid is not None, "the session did not get going"
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(30)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()
    with Record(data) as rec:
        before = rec.captures(sid)
        assert rec.get_session(sid).state in ("running", "awaiting_operator")  # nobody could say otherwise
        for cap in before:  # every capture that has a row has its complete, checked image
            rec.load_image(cap)
    listed = json.loads(station("sessions", "--json", "--data", str(data)).stdout)
    assert listed[0]["state"] == "interrupted"
    p = station("run", "--resume", sid, "--sim", "--data", str(data), "--json")
    assert p.returncode == 0, p.stderr
    doc = last_json(p.stdout)
    assert doc["id"] == sid
    assert doc["state"] == "succeeded"
    assert doc["results"]["tests"]["J2"]["n_cycles"] == 12
    with Record(data) as rec:
        after = rec.captures(sid)
        assert {c.id for c in before} <= {c.id for c in after}  # nothing captured before the kill was lost
        # the interrupted test ran again from its start: its reference captured again, in the resumed run
        assert any(c.meta.get("run") == 1 and c.meta["role"] == "reference" for c in after)


def test_the_example_script_runs_a_repeatability_session(tmp_path: Path) -> None:
    script = Path(__file__).resolve().parents[2] / "examples" / "repeatability.py"
    p = subprocess.run(
        [
            sys.executable,
            str(script),
            "--sim",
            "--cycles",
            "3",
            "--joints",
            "1",
            "5",
            "--data",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert p.returncode == 0, p.stderr
    assert "J1: RP" in p.stdout
    assert "seed 0.05299" in p.stdout  # J5 beside the seed's Table 2
    report = Path(p.stdout.split("report: ")[1].strip())
    assert report.exists()


def test_measure_with_the_stations_scale_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import cv2

    from station.cli import main
    from station.testing import draw_cross

    image = tmp_path / "cross.png"
    cv2.imwrite(str(image), draw_cross(center_px=(330.0, 250.0)))
    cal = tmp_path / "scale-calibration.json"
    cal.write_text(json.dumps({"groove_width_mm": 0.770, "u_mm": 0.0004, "session_id": "abcd1234ef56"}))
    assert main(["measure", "--json", str(image)]) == 0
    plain = last_json(capsys.readouterr().out)
    assert main(["measure", "--json", "--scale-calibration", str(cal), str(image)]) == 0
    calibrated = last_json(capsys.readouterr().out)
    assert calibrated["diagnostics"]["scale_calibration"]["session_id"] == "abcd1234ef56"
    assert calibrated["diagnostics"]["params"]["groove_width_mm"] == 0.770
    ratio = calibrated["center_mm"][0] / plain["center_mm"][0]
    assert abs(ratio - 0.770 / (25.4 / 32)) < 1e-6  # every length scales with the groove width
    bad = tmp_path / "bad.json"
    bad.write_text('{"groove_width_mm": -1}')
    with pytest.raises(SystemExit) as info:
        main(["measure", "--json", "--scale-calibration", str(bad), str(image)])
    assert info.value.code == 2
    assert "not a scale calibration" in capsys.readouterr().err
