"""Views the ruler measurement must refuse, each with its own code and a message that says what to do."""

from __future__ import annotations

import numpy as np
import pytest

from sim._render_camera import pose_for_center_px
from sim.artifact import render
from sim.ruler import render_ruler, ruler_truth
from station.vision import (
    CodeInconsistentError,
    CodeUnreadableError,
    ImageQualityError,
    MeasurementError,
    OffRulerError,
    RulerCode,
    RulerParams,
    RulerSpec,
    TooFewGraduationsError,
    measure_ruler,
)


def _refused(image: np.ndarray, error: type[MeasurementError], params: RulerParams | None = None) -> str:
    with pytest.raises(error) as info:
        measure_ruler(image, params)
    assert info.value.code == error.code
    return info.value.message


def test_a_blank_frame() -> None:
    message = _refused(np.full((480, 640), 120, np.uint8), ImageQualityError)
    assert "illumination" in message


@pytest.mark.parametrize(
    "image",
    [
        np.random.default_rng(1).integers(0, 256, (480, 640), dtype=np.uint8),
        render(pose_for_center_px(320, 240, rotation_deg=5.0), rng=np.random.default_rng(2))[0],
    ],
    ids=["noise", "the cross"],
)
def test_no_ruler_in_view(image: np.ndarray) -> None:
    message = _refused(image, OffRulerError)
    assert "bring the ruler" in message or "not the ruler's pattern" in message


def test_the_pattern_runs_out_of_the_frame_across_the_ruler() -> None:
    # the ruler along x with its axis 70 px from the top: the upper part of the lines is cut off
    image, _ = render_ruler(pose_for_center_px(320, 70), anchor_mm=90.0, rng=np.random.default_rng(3))
    message = _refused(image, OffRulerError)
    assert "move the view" in message or "whole pattern" in message


def test_the_end_of_the_ruler() -> None:
    # graduation 0 at x = 410: under 5 periods of graduations in view, the blank ruler beyond
    image, truth = render_ruler(pose_for_center_px(560, 240), anchor_mm=1.5, rng=np.random.default_rng(4))
    assert truth.position_mm < -4.0  # the origin pixel is beyond the ruler's start
    message = _refused(image, TooFewGraduationsError)
    assert "end of the ruler" in message


def test_beside_the_end_of_the_ruler_with_enough_graduations() -> None:
    # graduation 0 at x = 170: measured, from the graduations alone (the window holding the end is
    # left out: its profile is cut, not shifted)
    image, truth = render_ruler(pose_for_center_px(320, 240), anchor_mm=1.5, rng=np.random.default_rng(4))
    m = measure_ruler(image)
    assert abs(m.position_mm - truth.position_mm) * 100 <= 0.006


def test_too_short_a_stretch_of_the_pattern() -> None:
    # the ruler across a corner of the frame: its whole width is in view over one period only
    image, _ = render_ruler(
        pose_for_center_px(130, 130, rotation_deg=-45.0), anchor_mm=50.0, rng=np.random.default_rng(5)
    )
    message = _refused(image, TooFewGraduationsError)
    assert "centre the ruler" in message


def test_a_code_track_painted_over() -> None:
    pose = pose_for_center_px(320, 240, rotation_deg=8.0)
    image, _ = render_ruler(pose, anchor_mm=70.0, rng=np.random.default_rng(6))
    truth = ruler_truth(pose, anchor_mm=70.0)
    h_inv = np.linalg.inv(truth.homography)
    ys, xs = np.mgrid[0:480, 0:640]
    p = h_inv @ np.stack([xs.ravel(), ys.ravel(), np.ones(xs.size)])
    t = (p[1] / p[2]).reshape(480, 640)
    blotted = image.copy()
    blotted[(t > -0.13) & (t < 0.53)] = 122  # mid-grey over the code track (t -0.1 to 0.5 mm)
    message = _refused(blotted, CodeUnreadableError)
    assert "clean the ruler's code track" in message


def test_another_rulers_code() -> None:
    image, _ = render_ruler(
        pose_for_center_px(320, 240, rotation_deg=-12.0), anchor_mm=140.0, rng=np.random.default_rng(7)
    )
    other = RulerParams(ruler=RulerSpec(name="other", code=RulerCode(taps=(11, 2))))
    message = _refused(image, CodeInconsistentError, other)
    assert "is this the ruler described" in message


def test_a_mirrored_image() -> None:
    # seen through a mirror the pattern keeps its layout but the code runs backwards
    image, _ = render_ruler(
        pose_for_center_px(320, 240, rotation_deg=3.0), anchor_mm=180.0, rng=np.random.default_rng(8)
    )
    message = _refused(np.ascontiguousarray(image[:, ::-1]), CodeInconsistentError)
    assert "mirrored" in message
