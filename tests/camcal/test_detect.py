"""Finding the target in a view, against the twin's truth."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from sim.artifact import pose_for_center_px, render
from sim.lens import true_intrinsics
from sim.presets import get_preset
from sim.target import TargetPose, render_target
from station.camcal import TargetNotFoundError, ViewSpec, detect_target, refine_corners
from station.vision import ImageQualityError

TRUTH = true_intrinsics(4)
QUIET = replace(
    get_preset("nominal"), name="quiet", read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0, vignetting=0.0
)


def _view(view: ViewSpec, seed: int = 0, **kw):
    return render_target(TargetPose.from_view(view), intrinsics=TRUTH, rng=np.random.default_rng(seed), **kw)


def test_finds_the_corners_of_a_view_where_they_are() -> None:
    image, truth = _view(ViewSpec(turn_deg=25.0))
    found = detect_target(image)
    assert found.count >= 100  # of about 120 in the frame
    assert set(found.ids) <= set(np.flatnonzero(truth.in_frame))
    error = np.hypot(*(found.corners_px - truth.corners_px[found.ids]).T)
    assert np.sqrt(np.mean(error**2)) < 0.02  # 0.009 px per axis measured
    assert error.max() < 0.06
    np.testing.assert_array_equal(found.object_mm, found.object_mm[np.argsort(found.ids)])
    assert found.image_size == (640, 480)
    assert 0.7 < found.coverage() < 1.0


def test_refinement_has_no_pixel_locking_where_cornersubpix_has() -> None:
    image, truth = _view(ViewSpec(turn_deg=7.0), preset=QUIET, defocus_px_per_mm=0.0)
    found = detect_target(image)
    start = found.corners_px + 0.3  # a start off the corner: the refinement must converge to it
    refined, ok = refine_corners(image, start)
    assert ok.all()
    ours = np.hypot(*(refined - truth.corners_px[found.ids]).T)
    assert np.sqrt(np.mean(ours**2)) < 0.006  # noise-free but 8-bit: rounding only (0.004 px measured)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 200, 1e-6)
    opencv = cv2.cornerSubPix(image, start.astype(np.float32).reshape(-1, 1, 2), (6, 6), (-1, -1), criteria)
    theirs = np.hypot(*(opencv.reshape(-1, 2) - truth.corners_px[found.ids]).T)
    assert np.sqrt(np.mean(theirs**2)) > 2 * np.sqrt(np.mean(ours**2))  # why cornerSubPix is not used


def test_refinement_refuses_what_is_not_a_corner() -> None:
    flat = np.full((100, 100), 128, dtype=np.uint8)
    flat[:, 50:] = 200  # a straight edge: no point to converge to along it
    points, ok = refine_corners(flat, np.array([[50.0, 50.0], [3.0, 50.0]]))
    assert not ok.any()  # ill-conditioned, and a window off the frame
    np.testing.assert_array_equal(points, [[50.0, 50.0], [3.0, 50.0]])


def test_a_16bit_frame_is_read_like_its_8bit_one() -> None:
    image, _ = _view(ViewSpec())
    wide = image.astype(np.uint16) * 257
    a, b = detect_target(image), detect_target(wide)
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_allclose(a.corners_px, b.corners_px, atol=1e-9)


def test_no_target_in_view_says_what_to_do() -> None:
    cross, _ = render(pose_for_center_px(320.0, 240.0), rng=np.random.default_rng(0))
    with pytest.raises(TargetNotFoundError, match="no marker was decoded; is the calibration target") as err:
        detect_target(cross)
    assert err.value.code == "target_not_found"


def test_too_few_corners_out_of_focus() -> None:
    image, _ = _view(ViewSpec(height_mm=0.5), defocus_px_per_mm=20.0)  # 10 px of blur: no marker readable
    with pytest.raises(TargetNotFoundError, match=r"found \d+ of the target's corners"):
        detect_target(image)


def test_a_blank_frame_is_an_image_problem_not_a_missing_target() -> None:
    with pytest.raises(ImageQualityError, match="blank"):
        detect_target(np.full((480, 640), 90, dtype=np.uint8))
    with pytest.raises(ValueError, match="min_corners must be >= 4"):
        detect_target(np.zeros((480, 640), np.uint8), min_corners=3)
