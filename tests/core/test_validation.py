"""The seed's validation (section 4) and parameter sweep (Table 1) on a simulated table series."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from sim.imageset import render_validation_set
from station.cli import main
from station.displacements import validate
from station.imagesets import ImageSetError, load_set, read_displacements
from station.parameter_study import SEED_TABLE_1, parse_grid, seed_trials
from station.vision import MeasureParams, centre, series_centers_mm, series_homography, square_homography


@pytest.fixture(scope="module")
def vset(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return render_validation_set(tmp_path_factory.mktemp("v") / "set", preset="nominal", seed=5)


@pytest.fixture(scope="module")
def short_set(vset: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first 14 positions of the pattern (two sides): a valid, smaller validation set."""
    out = tmp_path_factory.mktemp("short") / "set"
    out.mkdir()
    lines = (vset / "displacements.csv").read_text().splitlines()[:15]
    (out / "displacements.csv").write_text("\n".join(lines) + "\n")
    for line in lines[1:]:
        shutil.copy(vset / line.split(",")[0], out)
    return out


def test_precise_series_validation_meets_the_displacement_target(vset: Path) -> None:
    s = load_set(vset)
    series = validate(s, MeasureParams(), calibration="series")
    per_image = validate(s, MeasureParams(), calibration="image")
    assert series.used.all()
    # bound with margin over the measured 0.011 / 0.024 um (bench): issue target 0.10 / 0.30 um
    assert series.comparison.rigid.mean < 0.05
    assert series.comparison.rigid.max < 0.15
    assert series.comparison.similarity.scale == pytest.approx(1.0, abs=1e-3)
    # one homography for the series removes the amplified per-image scale noise
    assert per_image.comparison.rigid.mean > 3 * series.comparison.rigid.mean
    assert series.center_error_px is not None
    assert series.center_error_px.max() < 0.01


def test_validate_cli_json_and_errors(capsys: pytest.CaptureFixture[str], vset: Path, tmp_path: Path) -> None:
    assert (
        main(["validate", "--json", "-j", "1", "--mode", "paper", "--calibration", "image", str(vset)]) == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["mode"] == "paper"
    assert doc["calibration"] == "image"
    assert doc["measured"] == 40
    assert {"rigid", "similarity", "affine"} <= set(doc)
    # Paper mode with the seed's per-image scale: its moment's bias changes with each 0.5 px step of
    # the edge's sub-pixel phase, the groove width with it, and the image origin ~250 px away moves by
    # tens of micrometres (48 um max measured on this set; the seed reported 16.8 um on its bench).
    assert doc["affine"]["max_um"] < 100.0
    assert main(["validate", "--json", "-j", "1", "--mode", "paper", str(vset)]) == 0
    series = json.loads(capsys.readouterr().out)
    assert series["calibration"] == "series"
    assert series["affine"]["max_um"] < 2.0
    (tmp_path / "a.png").write_bytes((vset / "img_000.png").read_bytes())
    assert main(["validate", str(tmp_path)]) == 1
    assert "no displacements.csv" in capsys.readouterr().err
    assert main(["validate", str(tmp_path / "nowhere")]) == 1
    assert "not a folder" in capsys.readouterr().err


def test_series_homography_recovers_a_common_scale_from_noisy_corners() -> None:
    rng = np.random.default_rng(0)
    side = 80.0
    w = 0.79375
    shifts = rng.uniform(-5, 5, (30, 2))
    base = np.array([[300.0, 200.0], [380.0, 200.0], [380.0, 280.0], [300.0, 280.0]])
    corners = [base + s + rng.normal(0, 0.01, (4, 2)) for s in shifts]
    centres = [tuple(base.mean(axis=0) + s) for s in shifts]
    H = series_homography(corners, w)
    np.testing.assert_allclose(np.linalg.norm(H[:2, :2] / H[2, 2], axis=0), w / side, rtol=1e-4)
    truth = (shifts - shifts[0]) * w / side
    mm = series_centers_mm(centres, corners, w)
    series_error = np.abs(mm - mm[0] - truth).max()
    per_image = np.array([centre(square_homography(c, w), w)[0] for c in corners])
    per_image_error = np.abs(per_image - per_image[0] - truth).max()
    assert series_error < 5e-6  # mm
    assert per_image_error > 5 * series_error


def test_sweep_reproduces_table_1_layout(capsys: pytest.CaptureFixture[str], short_set: Path) -> None:
    assert main(["sweep", "-j", "1", str(short_set)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].split() == ["Trial", "Filter", "SK", "TW", "TH", "MaxE", "MeanE", "best"]
    rows = [line.split() for line in lines[2:11]]
    assert [r[:5] for r in rows] == [
        [str(n), f.capitalize(), str(sk), str(tw), str(th)] for n, f, sk, tw, th, _, _ in SEED_TABLE_1
    ]
    assert sum(r[-1] == "*" for r in rows) == 1
    assert "TW = TESTWIDTH, TH = TESTHEIGHT" in out
    assert all(float(r[5]) >= float(r[6]) for r in rows)  # MaxE >= MeanE


def test_sweep_custom_grid_json_and_bad_grid(capsys: pytest.CaptureFixture[str], short_set: Path) -> None:
    assert (
        main(
            [
                "sweep",
                "--json",
                "-j",
                "1",
                "--grid",
                "SKIP=1,10",
                "--grid",
                "filter=none,mean",
                str(short_set),
            ]
        )
        == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert [t["params"] for t in doc["trials"]] == [
        {"skip": "1", "filter": "none"},
        {"skip": "1", "filter": "mean"},
        {"skip": "10", "filter": "none"},
        {"skip": "10", "filter": "mean"},
    ]
    assert doc["best"] in (1, 2, 3, 4)
    for bad in (["--grid", "SKIP"], ["--grid", "nope=1,2"], ["--grid", "skip=0,1"]):
        with pytest.raises(SystemExit) as exc:
            main(["sweep", *bad, str(short_set)])
        assert exc.value.code == 2
    assert seed_trials()[6] == {"filter": "none", "skip": 1, "testwidth": 5, "testheight": 5}
    assert parse_grid(["TestWidth=5,25"]) == {"testwidth": ["5", "25"]}


def test_image_set_reader_names_the_bad_line(tmp_path: Path) -> None:
    csv = tmp_path / "displacements.csv"
    csv.write_text("file,dx,dy\n")
    with pytest.raises(ImageSetError, match="header"):
        read_displacements(csv)
    csv.write_text("file,dx_um,dy_um\na.png,1.0,x\n")
    with pytest.raises(ImageSetError, match=r"displacements.csv:2: displacement is not a number"):
        read_displacements(csv)
    csv.write_text("file,dx_um,dy_um\na.png,1.0\n")
    with pytest.raises(ImageSetError, match=":2: expected 3 fields"):
        read_displacements(csv)
    (tmp_path / "empty").mkdir()
    with pytest.raises(ImageSetError, match="no images"):
        load_set(tmp_path / "empty")
