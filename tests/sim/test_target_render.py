"""The calibration target's twin: a true lens that differs from the nominal, frames with exact truth."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from sim.artifact import CameraSpec
from sim.lens import nominal_intrinsics, true_intrinsics
from sim.presets import get_preset
from sim.target import TargetPose, render_target
from sim.target_sensor import sensor_distance
from station.camcal import STANDARD_TARGET, ViewSpec
from station.camera_model import CameraIntrinsics

QUIET = replace(
    get_preset("nominal"), name="quiet", read_noise_dn=0.0, shot_noise_gain_dn_per_e=0.0, vignetting=0.0
)


def test_true_lens_is_seeded_and_within_its_ranges() -> None:
    nominal = CameraSpec()
    cams = [true_intrinsics(seed) for seed in range(40)]
    assert true_intrinsics(7).camera_matrix.tolist() == true_intrinsics(7).camera_matrix.tolist()
    fx = np.array([c.fx for c in cams]) / nominal.focal_px - 1
    cx = np.array([c.principal_point[0] for c in cams]) - nominal.principal_point[0]
    assert np.all(np.abs(fx) <= 0.02)
    assert np.abs(fx).max() > 0.01  # the range is used, not a token deviation
    assert np.all(np.abs(cx) <= 20.0)
    assert np.abs(cx).max() > 10.0
    assert all(c.coefficient("p1") == 0.0 for c in cams)
    assert true_intrinsics(3, tangential_px=1.0).coefficient("p1") != 0.0
    # k1 moves the corner of the frame by at most radial_px
    corner = np.array([[[0.0, 0.0]]])
    for c in cams[:5]:
        ideal = cv2.undistortPoints(corner, c.camera_matrix, c.dist_coeffs, P=c.camera_matrix)
        assert np.hypot(*(ideal - corner).ravel()) <= 2.0 * 1.05
    assert nominal_intrinsics().image_size == (640, 480)


def test_corners_render_where_the_truth_says() -> None:
    lens = true_intrinsics(11)
    pose = TargetPose.from_view(ViewSpec(tilt_deg=10.0, azimuth_deg=60.0, turn_deg=15.0))
    image, truth = render_target(
        pose, intrinsics=lens, preset=QUIET, defocus_px_per_mm=0.0, rng=np.random.default_rng(0)
    )
    # The truth is OpenCV's projection with the true lens...
    expected, _ = cv2.projectPoints(
        STANDARD_TARGET.corners_mm(), pose.rvec, pose.translation_mm, lens.camera_matrix, lens.dist_coeffs
    )
    np.testing.assert_allclose(truth.corners_px, expected.reshape(-1, 2), atol=1e-9)
    # ...and the frame's saddles are there: a corner's four quadrants are point-symmetric about it.
    inside = np.flatnonzero(
        truth.in_frame
        & (truth.corners_px[:, 0] > 20)
        & (truth.corners_px[:, 0] < 619)
        & (truth.corners_px[:, 1] > 20)
        & (truth.corners_px[:, 1] < 459)
    )
    assert inside.size > 80
    img = image.astype(np.float64)
    for i in inside[::9]:
        x, y = truth.corners_px[i]
        a = cv2.getRectSubPix(img.astype(np.float32), (9, 9), (x, y)).astype(np.float64)
        assert (
            np.abs(a - a[::-1, ::-1]).max() < 6.0
        )  # DN, of 165 between black and white; rounding + bilinear


def test_frame_is_seeded_and_the_target_is_black_and_white() -> None:
    lens = true_intrinsics(2)
    pose = TargetPose.from_view(ViewSpec())
    a, _ = render_target(pose, intrinsics=lens, rng=np.random.default_rng(3))
    b, _ = render_target(pose, intrinsics=lens, rng=np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    p = get_preset("nominal")
    assert abs(np.percentile(a, 2) - p.paint_level_dn) < 6
    assert abs(np.percentile(a, 98) - p.land_level_dn) < 8


def test_defocus_grows_with_the_distance_from_focus() -> None:
    lens = true_intrinsics(2)

    def sharpness(height_mm: float) -> float:
        image, truth = render_target(
            TargetPose.from_view(ViewSpec(height_mm=height_mm)),
            intrinsics=lens,
            preset=QUIET,
            defocus_px_per_mm=3.1,
            rng=np.random.default_rng(0),
        )
        assert truth.blur_px.min() == pytest.approx(np.hypot(1.0, 3.1 * height_mm), rel=1e-6)
        return float(np.mean(np.abs(np.diff(image.astype(float), axis=1))))

    assert sharpness(0.0) > sharpness(0.3) > sharpness(0.8)


def test_sensor_reads_the_plane_along_its_beam() -> None:
    mount = np.eye(4)
    mount[:3, 3] = (30.0, 0.0, -2.0)
    rng = np.random.default_rng(0)
    square = TargetPose.from_view(ViewSpec())
    higher = TargetPose.from_view(ViewSpec(height_mm=0.4))
    r0 = sensor_distance(square, mount, rng=rng, samples=400)
    r1 = sensor_distance(higher, mount, rng=rng, samples=400)
    assert r0 == pytest.approx(68.0 + 2.0, abs=0.0005)  # 2 um repeatability over 400 samples
    assert r1 - r0 == pytest.approx(0.4, abs=0.0005)


def test_refuses_what_it_cannot_render() -> None:
    lens = true_intrinsics(2)
    pose = TargetPose.from_view(ViewSpec())
    with pytest.raises(ValueError, match="needs its image size"):
        render_target(
            pose,
            intrinsics=CameraIntrinsics(lens.camera_matrix, lens.dist_coeffs),
            rng=np.random.default_rng(0),
        )
    odd = STANDARD_TARGET.model_copy(update={"marker_mm": 0.333})
    with pytest.raises(ValueError, match="whole numbers of marker bits"):
        render_target(pose, intrinsics=lens, target=odd, rng=np.random.default_rng(0))
    with pytest.raises(ValueError, match="proper rotation"):
        TargetPose(np.diag([1.0, 1.0, -1.0]), np.zeros(3))
