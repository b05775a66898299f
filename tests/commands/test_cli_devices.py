"""`station camera` and `station table` on the simulated station."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from station.cli import main


def test_sim_camera_grab_writes_a_frame_that_measure_measures(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    out = tmp_path / "out.png"
    assert main(["camera", "--sim", "--json", "grab", str(out)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["width"], info["height"], info["dtype"]) == (640, 480, "uint8")
    assert main(["measure", "--json", "-j", "1", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ok"] is True
    # the simulated station is set up with the crossing on the optical axis at the reference pose
    assert abs(doc["center_px"][0] - 319.5) < 0.05
    assert abs(doc["center_px"][1] - 239.5) < 0.05


def test_camera_errors_are_specific(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert main(["camera", "--v4l2", "/dev/video-none", "grab", str(tmp_path / "x.png")]) == 1
    assert "no V4L2 device at /dev/video-none" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:  # refused before anything is grabbed (issue 13)
        main(["camera", "--sim", "--average", "2", "grab", str(tmp_path / "x.unknown")])
    assert exit_info.value.code == 2
    assert "not a lossless format" in capsys.readouterr().err


def test_sim_table_move_goes_through_the_operator_prompt(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["table", "--sim", "--json", "move", "0.0254", "0.00508"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == {"x_mm": pytest.approx(0.0254), "y_mm": pytest.approx(0.00508)}
    assert "set X to 0.0010 in, Y to 0.0002 in, then confirm" in captured.err
    assert "confirmed by sim-operator" in captured.err
    assert main(["table", "--sim", "move", "30", "0"]) == 1
    assert "outside its travel" in capsys.readouterr().err
