"""A validation with a ruler on the simulated X-Y table (issue 22, item 4), against the world's truth.

The table carries a ruler in place of the crossed artifact (``WorldSpec.table_artifact``); every frame is
measured with ``measure_ruler`` (an absolute position along the ruler, no homography across the series)
and compared with where the world really moved the ruler.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from sim.station import build_sim_station
from sim.world import WorldSpec
from station.devices import Frame
from station.kinds import get_plan
from station.metrology import fit_rigid
from station.plans import parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from tests.sessions.conftest import results_of, sid_of

#: A small pattern (um, multiples of the sim micrometers' 0.0002 in), both directions, both axes.
PATTERN_UM = [[0, 0], [254, 0], [508, 0], [508, 254], [254, 508], [0, 254], [0, 508]]


@pytest.fixture
def record(tmp_path: Path) -> Iterator[Record]:
    rec = Record(tmp_path / "data")
    yield rec
    rec.close()


def test_a_ruler_validation_measures_the_true_table_displacements(record: Record) -> None:
    spec = replace(WorldSpec(), table_artifact="ruler")
    devices = build_sim_station(spec=spec, seed=11)
    world = devices.truth.world
    ruler_at: dict[int, np.ndarray] = {}  # the table's ruler (the world's last) in every frame grabbed
    real_grab = devices.camera.grab

    def grab(timeout_s: float = 2.0) -> Frame:
        frame = real_grab(timeout_s)
        ruler_at[frame.frame_id] = world.ruler_poses()[-1]
        return frame

    devices.camera.grab = grab  # type: ignore[method-assign]
    plan = get_plan("validation")
    params = parse_params(plan, {"artifact": "ruler", "pattern_um": PATTERN_UM})
    runner = SessionRunner(record, plan, params, devices=devices)
    try:
        runner.run()
    finally:
        devices.close_owned()
    assert runner.state is SessionState.SUCCEEDED, runner.error
    res = results_of(record, runner)
    caps = record.captures(sid_of(runner))
    assert len(caps) == len(PATTERN_UM)
    measurements = record.measurements(sid_of(runner))
    assert all(m.result["artifact"] == "ruler" and m.result["ok"] for m in measurements)
    # the ruler's true displacement in its own axes (um) against what the station measured
    F0 = ruler_at[caps[0].meta["frame_id"]]
    true_um = np.array(
        [(F0[:3, :3].T @ (ruler_at[c.meta["frame_id"]][:3, 3] - F0[:3, 3]))[:2] * 1000.0 for c in caps]
    )
    measured_um = np.array([p["measured_um"] for p in res["positions"]])
    fit = fit_rigid(true_um, measured_um)
    assert fit.mean <= 0.05, f"raw mean error {fit.mean:.4f} um against the world's truth (bound 0.05)"
    assert fit.max <= 0.15, f"raw max error {fit.max:.4f} um against the world's truth (bound 0.15)"
    assert res["artifact"] == "ruler"
    assert res["groove_width_mm"] is None
    assert res["scale_calibration"] is None
    names = {c["name"] for c in res["checks"]}
    assert "groove_width" not in names
    assert {"table_moves", "rigid_mean", "rigid_max"} <= names
    # against the commanded pattern: the sim table's own imperfections (skew 0.05 deg), no more
    assert res["mean_um"] < 0.5


def test_station_run_validation_takes_the_artifact_parameter(tmp_path: Path) -> None:
    """``station run validation --param artifact=ruler`` as a user gives it: the simulated operator puts
    a ruler on the table, the session measures it; ``reanalyse`` measures it again as a ruler."""
    data = tmp_path / "data"
    args = [sys.executable, "-m", "station.cli", "run", "validation", "--sim", "--data", str(data)]
    pattern = ["--param", "pattern_um=[[0, 0], [254, 0], [0, 254], [254, 254]]", "--json"]
    p = subprocess.run(
        [*args, "--param", "artifact=ruler", *pattern], capture_output=True, text=True, timeout=240
    )
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout.strip().splitlines()[-1])
    assert doc["state"] == "succeeded"
    assert doc["results"]["artifact"] == "ruler"
    assert doc["results"]["mean_um"] < 0.5
    assert doc["results"]["groove_width_mm"] is None
    # a re-analysis measures the ruler's frames with the ruler's measurement again: the same results
    again = subprocess.run(
        [*args[:3], "run", "reanalyse", "--param", f"session={doc['id']}", "--data", str(data), "--json"],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert again.returncode == 0, again.stderr
    original = dict(doc["results"])
    # the controller's self-test is the live session's (station.selftest_status), not its images'
    original.pop("selftest", None)
    original["checks"] = [c for c in original["checks"] if c["name"] != "selftest"]
    assert json.loads(again.stdout.strip().splitlines()[-1])["results"]["validation"] == original


def test_an_unknown_artifact_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from station.cli import main

    code = main(["run", "validation", "--sim", "--param", "artifact=rule", "--data", str(tmp_path / "d")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "artifact" in err
    assert "ruler" in err
    assert "Traceback" not in err
