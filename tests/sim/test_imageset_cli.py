"""``station sim render-set`` and ``station sim render``, called in-process."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest

from sim.imageset import load_displacements, load_truth
from station.cli import main


def test_render_set_validation_as_make_run_calls_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "validation-nominal"
    argv = ["sim", "render-set", str(out), "--pattern", "validation", "--preset", "nominal", "--seed", "1"]
    assert main([*argv, "--force", "--table-rotation-deg", "1.5", "--table-skew-deg", "0.3"]) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == str(out)
    assert "40 validation images" in captured.err
    assert "nominal v1" in captured.err
    truth = load_truth(out)
    assert truth.table is not None
    assert (truth.table.rotation_deg, truth.table.skew_deg) == (1.5, 0.3)
    assert len(load_displacements(out)) == 40


def test_render_set_random_with_options(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "random"
    argv = ["sim", "render-set", str(out), "--pattern", "random", "--preset", "hard", "--count", "2"]
    assert main([*argv, "--seed", "7", "--max-rotation", "30", "--true-width-mm", "0.75"]) == 0
    truth = load_truth(out)
    assert (truth.kind, len(truth.images), truth.seed) == ("random", 2, 7)
    assert truth.artifact.groove_width_mm == 0.75
    assert truth.preset.name == "hard"
    assert capsys.readouterr().out.strip() == str(out)


def test_render_set_refuses_a_non_empty_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "something").write_text("x")
    assert main(["sim", "render-set", str(tmp_path), "--pattern", "random", "--count", "1"]) == 1
    captured = capsys.readouterr()
    assert "not empty" in captured.err
    assert "--force" in captured.err
    assert "Traceback" not in captured.err
    assert captured.out == ""


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--count", "3"], "--pattern random only"),
        (["--pattern", "random", "--table-skew-deg", "1"], "--pattern validation only"),
        (["--true-width-mm", "-1"], "groove_width_mm"),
        (["--pattern", "random", "--count", "0"], "count"),
    ],
)
def test_render_set_user_errors_exit_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], extra: list[str], message: str
) -> None:
    assert main(["sim", "render-set", str(tmp_path / "x"), *extra]) == 1
    assert message in capsys.readouterr().err


def test_unknown_preset_is_a_usage_error(tmp_path: Path) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["sim", "render-set", str(tmp_path), "--preset", "foggy"])
    assert exc.value.code == 2


def test_render_one_image_with_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png, truth_json = tmp_path / "one.png", tmp_path / "one.json"
    argv = ["sim", "render", str(png), "--center-px", "300.25", "250.5", "--rotation", "4", "--tilt-x", "0.5"]
    assert main([*argv, "--preset", "hard", "--seed", "2", "--truth", str(truth_json)]) == 0
    assert capsys.readouterr().out.strip() == str(png)
    image = cv2.imread(str(png), cv2.IMREAD_UNCHANGED)
    assert image is not None
    assert image.shape == (480, 640)
    doc = json.loads(truth_json.read_text())
    assert doc["center_px"] == pytest.approx([300.25, 250.5])
    assert doc["pose"]["rotation_deg"] == 4.0
    assert doc["preset"]["name"] == "hard"


def test_render_one_rejects_an_unwritable_format(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "render", str(tmp_path / "one.unknown")]) == 1
    assert "station sim:" in capsys.readouterr().err
