"""Truth geometry: the camera model, pose conventions and the Truth record."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.testing import assert_allclose

from sim.artifact import (
    ArtifactSpec,
    CameraSpec,
    Pose,
    Truth,
    homography_for,
    pose_for_center_px,
    truth_for,
)

W = 25.4 / 32
TILTED = pose_for_center_px(300.4, 255.9, rotation_deg=6.0, tilt_x_deg=0.9, tilt_y_deg=-0.7, z_mm=0.2)


def _apply(h: np.ndarray, uv: tuple[float, float]) -> np.ndarray:
    p = h @ np.array([uv[0], uv[1], 1.0])
    return np.asarray(p[:2] / p[2])


def test_untilted_corners_are_the_scaled_square_in_order() -> None:
    truth = truth_for(pose_for_center_px(320.25, 240.5))
    half = W / 2 * 100.0
    square = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    expected = square + np.array([320.25, 240.5])
    assert_allclose(truth.corners_px, expected, atol=1e-9)
    assert truth.center_px == pytest.approx((320.25, 240.5), abs=1e-12)
    assert truth.px_per_mm == 100.0
    assert truth.groove_width_mm == W


def test_centre_is_the_crossing_of_the_projected_diagonals() -> None:
    truth = truth_for(TILTED)
    c = truth.corners_px
    d1 = np.cross(np.append(c[0], 1), np.append(c[2], 1))
    d2 = np.cross(np.append(c[1], 1), np.append(c[3], 1))
    crossing = np.cross(d1, d2)
    assert_allclose(crossing[:2] / crossing[2], truth.center_px, atol=1e-9)
    assert not np.allclose(c.mean(axis=0), truth.center_px, atol=1e-4)  # perspective: mean is not centre


def test_lines_are_normalised_through_their_corners_with_normals_toward_increasing_uv() -> None:
    truth = truth_for(TILTED)
    a, b = truth.lines[:, 0], truth.lines[:, 1]
    assert_allclose(a**2 + b**2, 1.0, atol=1e-12)
    on = {0: (0, 1), 1: (2, 3), 2: (0, 3), 3: (1, 2)}  # top, bottom, left, right
    for edge, (i, j) in on.items():
        for k in (i, j):
            assert truth.corners_px[k] @ truth.lines[edge, :2] == pytest.approx(
                truth.lines[edge, 2], abs=1e-9
            )
    side = truth.lines[:, :2] @ np.array(truth.center_px) - truth.lines[:, 2]
    assert np.sign(side).tolist() == [1.0, -1.0, 1.0, -1.0]  # centre: v > -w/2, v < w/2, u > -w/2, u < w/2


def test_homography_maps_the_corners_onto_the_groove_square() -> None:
    truth = truth_for(TILTED)
    square = np.array([[0, 0], [W, 0], [W, W], [0, W]], dtype=np.float32)
    t = cv2.getPerspectiveTransform(truth.corners_px.astype(np.float32), square)
    centre = t @ np.append(truth.center_px, 1.0)
    assert_allclose(centre[:2] / centre[2], [W / 2, W / 2], atol=1e-5)
    for k, uv in enumerate([(-W / 2, -W / 2), (W / 2, -W / 2), (W / 2, W / 2), (-W / 2, W / 2)]):
        assert_allclose(_apply(truth.homography, uv), truth.corners_px[k], atol=1e-12)
    assert_allclose(truth.homography, homography_for(TILTED), atol=0)


@pytest.mark.parametrize("rotation", [0.0, 7.5, -30.0])
def test_rotation_turns_u_clockwise_on_screen(rotation: float) -> None:
    h = homography_for(pose_for_center_px(320, 240, rotation_deg=rotation))
    step = _apply(h, (1.0, 0.0)) - _apply(h, (0.0, 0.0))
    t = math.radians(rotation)
    assert_allclose(step, [100 * math.cos(t), 100 * math.sin(t)], atol=1e-9)
    down = _apply(h, (0.0, 1.0)) - _apply(h, (0.0, 0.0))
    assert_allclose(down, [-100 * math.sin(t), 100 * math.cos(t)], atol=1e-9)  # v: image +y at zero


@pytest.mark.parametrize(("du", "dv"), [(0.00508, 0.0), (0.0, -0.0254), (0.013, 0.021)])
def test_displaced_moves_the_centre_along_the_rotated_axes(du: float, dv: float) -> None:
    pose = pose_for_center_px(310.0, 250.0, rotation_deg=8.0)
    moved = truth_for(pose.displaced(du, dv)).center_px
    t = math.radians(8.0)
    expected = np.array([310.0, 250.0]) + 100 * np.array(
        [du * math.cos(t) - dv * math.sin(t), du * math.sin(t) + dv * math.cos(t)]
    )
    assert_allclose(moved, expected, atol=1e-9)


def test_displaced_tilted_artifact_brings_its_point_to_the_old_origin_image() -> None:
    moved = TILTED.displaced(0.03, -0.02)
    assert_allclose(truth_for(moved).center_px, _apply(homography_for(TILTED), (0.03, -0.02)), atol=1e-9)
    assert moved.z_mm != TILTED.z_mm  # moving within a tilted plane changes depth


def test_pose_for_center_px_images_the_origin_there() -> None:
    for pose in [TILTED, pose_for_center_px(12.5, 470.0, tilt_y_deg=1.0, z_mm=-0.3)]:
        truth = truth_for(pose)
        assert_allclose(truth.center_px, _apply(truth.homography, (0.0, 0.0)), atol=1e-12)
    assert truth_for(TILTED).center_px == pytest.approx((300.4, 255.9), abs=1e-9)
    assert pose_for_center_px(319.5, 239.5) == Pose(0.0, 0.0)


def test_tilt_x_moves_the_lower_side_away_and_z_shrinks_the_image() -> None:
    c = truth_for(pose_for_center_px(319.5, 239.5, tilt_x_deg=5.0)).corners_px
    top_length, bottom_length = c[1, 0] - c[0, 0], c[2, 0] - c[3, 0]
    assert bottom_length < top_length
    c = truth_for(pose_for_center_px(319.5, 239.5, tilt_y_deg=5.0)).corners_px
    assert c[2, 1] - c[1, 1] > c[3, 1] - c[0, 1]  # +x side nearer: right edge longer
    far = truth_for(pose_for_center_px(319.5, 239.5, z_mm=0.68))
    assert far.px_per_mm == pytest.approx(100 / 1.01)
    assert far.corners_px[1, 0] - far.corners_px[0, 0] == pytest.approx(W * 100 / 1.01)


def test_truth_round_trips_through_json() -> None:
    truth = truth_for(TILTED, artifact=ArtifactSpec(groove_width_mm=0.78))
    back = Truth.from_json(truth.to_json())
    for name in ("corners_px", "lines", "homography"):
        assert_allclose(getattr(back, name), getattr(truth, name), atol=0, rtol=0)
    assert back.center_px == truth.center_px
    assert back.pose == truth.pose
    assert (back.groove_width_mm, back.px_per_mm) == (0.78, truth.px_per_mm)
    assert Truth.from_json(truth.to_dict()).pose == TILTED
    with pytest.raises(ValueError, match="malformed"):
        Truth.from_dict({"center_px": [1, 2]})


def test_specs_reject_impossible_values() -> None:
    with pytest.raises(ValueError, match="groove_width_mm"):
        ArtifactSpec(groove_width_mm=-0.1)
    with pytest.raises(ValueError, match="corner_radius_mm"):
        ArtifactSpec(corner_radius_mm=1.0)
    with pytest.raises(ValueError, match="16 px"):
        CameraSpec(width=8)
    with pytest.raises(ValueError, match="finite"):
        Pose(x_mm=float("nan"), y_mm=0.0)
