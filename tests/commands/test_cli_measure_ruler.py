"""`station measure --artifact ruler`: the contract (issue 22), usage errors, and the cross's unchanged."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from sim._render_camera import CameraSpec, pose_for_center_px
from sim.artifact import render
from sim.ruler import render_ruler
from station.cli import main
from station.vision import RulerCode, RulerSpec

RULER_KEYS = {"file", "ok", "artifact", "position_mm", "offset_mm", "angle_deg", "code", "diagnostics"}
CROSS_KEYS = {"file", "ok", "center_px", "center_mm", "corners_px", "lines", "diagnostics"}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("ruler")
    out: dict[str, Path] = {}
    image, truth = render_ruler(
        pose_for_center_px(318.0, 244.0, rotation_deg=-7.0), anchor_mm=31.25, rng=np.random.default_rng(0)
    )
    cv2.imwrite(str(d / "ruler.png"), image)
    (d / "ruler_truth.json").write_text(truth.to_json())
    cross, _ = render(pose_for_center_px(310.4, 250.2, rotation_deg=4.0), rng=np.random.default_rng(1))
    cv2.imwrite(str(d / "cross.png"), cross)
    (d / "spec.json").write_text(RulerSpec(name="RS-0042").model_dump_json())
    (d / "other_code.json").write_text(RulerSpec(code=RulerCode(taps=(11, 2))).model_dump_json())
    (d / "bad_spec.json").write_text(json.dumps({"pitch_mm": 0.5, "length_mm": 250.1}))
    (d / "camera.json").write_text(
        json.dumps({"camera_matrix": CameraSpec().matrix().tolist(), "dist_coeffs": [0, 0, 0, 0, 0]})
    )
    for p in d.iterdir():
        out[p.stem] = p
    return out


def run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, list[str], str]:
    code = main(["measure", "-j", "1", *args])
    captured = capsys.readouterr()
    return code, captured.out.splitlines(), captured.err


def test_the_json_line_of_a_ruler_image(capsys: pytest.CaptureFixture[str], files: dict[str, Path]) -> None:
    code, out, _ = run(capsys, "--artifact", "ruler", "--json", str(files["ruler"]))
    assert code == 0
    doc = json.loads(out[0])
    assert set(doc) == RULER_KEYS
    assert doc["ok"] is True
    assert doc["artifact"] == "ruler"
    truth = json.loads(files["ruler_truth"].read_text())
    assert abs(doc["position_mm"] - truth["position_mm"]) * 100 <= 0.006
    assert abs(doc["offset_mm"] - truth["offset_mm"]) * 100 <= 0.25
    assert doc["angle_deg"] == pytest.approx(truth["angle_deg"], abs=0.03)
    assert doc["code"]["disagreements"] == 0
    assert doc["diagnostics"]["reference_px"] == [0.0, 0.0]


def test_a_failed_line_keeps_the_crosss_shape(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path]
) -> None:
    code, out, err = run(capsys, "--artifact", "ruler", "--json", str(files["ruler"]), str(files["cross"]))
    assert code == 1
    bad = json.loads(out[1])
    assert set(bad) == {"file", "ok", "error", "code"}
    assert bad["ok"] is False
    assert bad["code"] == "off_ruler"
    assert "cross.png" in err


def test_the_cross_stays_the_default(capsys: pytest.CaptureFixture[str], files: dict[str, Path]) -> None:
    code, out, _ = run(capsys, "--json", str(files["cross"]))
    assert code == 0
    assert set(json.loads(out[0])) == CROSS_KEYS
    code, out, _ = run(capsys, "--artifact", "cross", "--json", str(files["cross"]))
    assert set(json.loads(out[0])) == CROSS_KEYS


def test_the_text_table(capsys: pytest.CaptureFixture[str], files: dict[str, Path]) -> None:
    code, out, _ = run(capsys, "--artifact", "ruler", str(files["ruler"]))
    assert code == 0
    assert out[0].split() == ["file", "position_mm", "offset_mm", "angle_deg", "error"]
    assert "ruler.png" in out[2]


def test_a_ruler_description_file(capsys: pytest.CaptureFixture[str], files: dict[str, Path]) -> None:
    code, out, _ = run(
        capsys, "--artifact", "ruler", "--ruler", str(files["spec"]), "--json", str(files["ruler"])
    )
    assert code == 0
    assert json.loads(out[0])["diagnostics"]["ruler"] == "RS-0042"
    # a ruler with another code: this image's cells match no place of it
    code, out, _ = run(
        capsys, "--artifact", "ruler", "--ruler", str(files["other_code"]), "--json", str(files["ruler"])
    )
    assert code == 1
    assert json.loads(out[0])["code"] == "code_inconsistent"


def test_with_a_camera_model_under_the_principal_point(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path]
) -> None:
    code, out, _ = run(
        capsys, "--artifact", "ruler", "--camera-model", str(files["camera"]), "--json", str(files["ruler"])
    )
    assert code == 0
    doc = json.loads(out[0])
    assert doc["diagnostics"]["reference_px"] == list(CameraSpec().principal_point)
    truth = json.loads(files["ruler_truth"].read_text())
    assert abs(doc["position_mm"] - truth["principal_position_mm"]) * 100 <= 0.006


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--mode", "paper"], "--mode applies to the cross only"),
        (["--scale-calibration", "x.json"], "--scale-calibration applies to the cross only"),
        (["--set", "testwidth=5"], "unknown ruler parameter"),
        (["--set", "min_periods=1"], "min_periods"),
        (["--ruler", "/nonexistent.json"], "--ruler"),
    ],
)
def test_usage_errors(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path], args: list[str], message: str
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["measure", "--artifact", "ruler", *args, str(files["ruler"])])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_a_bad_ruler_description_is_a_usage_error(
    capsys: pytest.CaptureFixture[str], files: dict[str, Path]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["measure", "--artifact", "ruler", "--ruler", str(files["bad_spec"]), str(files["ruler"])])
    assert exit_info.value.code == 2
    assert "whole number of pitches" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["measure", "--ruler", str(files["spec"]), str(files["cross"])])
    assert exit_info.value.code == 2
    assert "--ruler applies to --artifact ruler only" in capsys.readouterr().err
