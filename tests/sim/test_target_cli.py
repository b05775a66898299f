"""``station sim render-target``, called in-process."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from station.camcal import detect_target
from station.cli import main


def test_render_target_writes_a_frame_the_detector_reads_and_its_truth(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, truth_file = tmp_path / "target.png", tmp_path / "truth.json"
    argv = ["sim", "render-target", str(out), "--lens-seed", "5", "--turn", "20", "--truth", str(truth_file)]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == str(out)
    assert "corners in the frame" in captured.err
    truth = json.loads(truth_file.read_text())
    assert (truth["camera_model"]["image_width"], truth["camera_model"]["image_height"]) == (640, 480)
    frame = cv2.imread(str(out), cv2.IMREAD_UNCHANGED)
    assert frame is not None
    found = detect_target(frame)
    expected = np.array([truth["corners_px"][i] for i in found.ids], dtype=float)
    assert np.hypot(*(found.corners_px - expected).T).max() < 0.06


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["x.jpg"], "written as PNG"),
        (["x.png", "--tilt", "75"], "tilt_deg must be in"),
        (["missing/x.png"], "could not write"),
    ],
)
def test_render_target_refuses_with_a_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    argv = ["sim", "render-target", str(tmp_path / args[0]), *args[1:]]
    assert main(argv) == 1
    assert message in capsys.readouterr().err
