"""The ruler measurement against the twin's truth (issue 22), with stated bounds.

The issue's targets, measured over 48 views per preset by ``python -m bench.ruler_bench``: position
error under the origin pixel, nominal, mean <= 0.002 px and max <= 0.006 px; hard, mean <= 0.01
px. Here, a few views: every one within the target's max (nominal) or 0.05 px (hard), and within 5
times the uncertainty the measurement states for itself (``diagnostics.position_u_nm``), so that the
stated uncertainty is honest.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim._render_camera import CameraSpec, Pose, pose_for_center_px
from sim.ruler import RulerTruth, render_ruler
from sim.ruler_imageset import random_ruler_views
from station.vision import MeasurementError, RulerMeasurement, RulerParams, RulerSpec, measure_ruler

PX_PER_MM = 100.0


def _errors(m: RulerMeasurement, truth: RulerTruth) -> tuple[float, float, float]:
    """Position and offset errors (px) and the angle's (deg)."""
    return (
        (m.position_mm - truth.position_mm) * truth.px_per_mm,
        (m.offset_mm - truth.offset_mm) * truth.px_per_mm,
        (m.angle_deg - truth.angle_deg + 180.0) % 360.0 - 180.0,
    )


@pytest.fixture(scope="module")
def nominal_views() -> list[tuple[np.ndarray, RulerTruth]]:
    rng = np.random.default_rng(11)
    return [render_ruler(pose, anchor_mm=a, rng=rng)[0:2] for pose, a in random_ruler_views(5, seed=11)]


def test_position_matches_the_twins_truth_nominal(nominal_views: list[tuple[np.ndarray, RulerTruth]]) -> None:
    for image, truth in nominal_views:
        m = measure_ruler(image)
        position, offset, angle = _errors(m, truth)
        u_px = m.extra["position_u_nm"] * 1e-6 * truth.px_per_mm
        assert abs(position) <= 0.006, (position, truth.pose)
        assert abs(position) <= 5 * u_px, (position, u_px)
        assert abs(offset) <= 0.25, offset
        assert abs(angle) <= 0.03, angle
        assert m.code.disagreements == 0


def test_position_matches_the_twins_truth_hard() -> None:
    rng = np.random.default_rng(12)
    for pose, anchor in random_ruler_views(3, seed=12):
        image, truth = render_ruler(pose, anchor_mm=anchor, preset="hard", rng=rng)
        m = measure_ruler(image)
        position, offset, angle = _errors(m, truth)
        u_px = m.extra["position_u_nm"] * 1e-6 * truth.px_per_mm
        assert abs(position) <= 0.05, (position, truth.pose)
        assert abs(position) <= 5 * u_px, (position, u_px)
        assert abs(offset) <= 0.4, offset
        assert abs(angle) <= 0.06, angle


@pytest.mark.parametrize("rotation_deg", [0.0, 90.0, 180.0, -90.0, 45.0, -135.0])
def test_every_direction_of_the_ruler_in_the_image(rotation_deg: float) -> None:
    # the pattern's asymmetry says which way +s runs: a ruler turned by 180 deg is read as such
    pose = pose_for_center_px(331.7, 228.2, rotation_deg=rotation_deg, tilt_x_deg=0.4, tilt_y_deg=-0.3)
    image, truth = render_ruler(pose, anchor_mm=123.4, rng=np.random.default_rng(3))
    m = measure_ruler(image)
    position, _, angle = _errors(m, truth)
    assert abs(position) <= 0.006
    assert abs(angle) <= 0.03


def test_with_a_camera_model_it_measures_under_the_principal_point() -> None:
    camera = CameraSpec()
    pose = pose_for_center_px(300.0, 260.0, rotation_deg=12.0, tilt_x_deg=0.5)
    image, truth = render_ruler(pose, anchor_mm=77.0, camera=camera, rng=np.random.default_rng(5))
    params = RulerParams(camera_matrix=camera.matrix().tolist(), dist_coeffs=[0.0, 0.0, 0.0, 0.0, 0.0])
    m = measure_ruler(image, params)
    assert m.reference_px == camera.principal_point
    assert abs(m.position_mm - truth.principal_position_mm) * PX_PER_MM <= 0.006
    assert abs(m.offset_mm - truth.principal_offset_mm) * PX_PER_MM <= 0.1
    # the same image without it: the origin pixel, 3 mm away
    plain = measure_ruler(image)
    assert abs(plain.position_mm - truth.position_mm) * PX_PER_MM <= 0.006
    assert abs(plain.position_mm - m.position_mm) > 1.0


def test_the_frame_maps_any_pixel_to_the_ruler(nominal_views: list[tuple[np.ndarray, RulerTruth]]) -> None:
    image, truth = nominal_views[0]
    m = measure_ruler(image)
    h = truth.homography
    for ds, dt in ((0.0, 0.0), (1.0, 0.5), (-1.5, -1.0)):
        p = h @ np.array([truth.anchor_mm + ds, dt, 1.0])
        s, t = m.to_ruler_mm(p[0] / p[2], p[1] / p[2])
        assert float(s) == pytest.approx(truth.anchor_mm + ds, abs=0.006 / PX_PER_MM)
        assert float(t) == pytest.approx(dt, abs=0.1 / PX_PER_MM)


def test_the_image_is_not_modified_and_other_depths_give_the_same_result(
    nominal_views: list[tuple[np.ndarray, RulerTruth]],
) -> None:
    image, _ = nominal_views[1]
    before = image.copy()
    m8 = measure_ruler(image)
    assert np.array_equal(image, before)
    m16 = measure_ruler(image.astype(np.uint16) * 257)
    colour = measure_ruler(np.repeat(image[:, :, None], 3, axis=2))
    assert m16.position_mm == pytest.approx(m8.position_mm, abs=1e-12)
    assert colour.position_mm == pytest.approx(m8.position_mm, abs=1e-12)


def test_the_json_object() -> None:
    image, _ = render_ruler(
        pose_for_center_px(320, 240, rotation_deg=5.0), anchor_mm=50.0, rng=np.random.default_rng(9)
    )
    doc = measure_ruler(image).to_json()
    assert set(doc) == {"ok", "artifact", "position_mm", "offset_mm", "angle_deg", "code", "diagnostics"}
    assert doc["ok"] is True
    assert doc["artifact"] == "ruler"
    assert set(doc["code"]) == {"first_cell", "bits", "read", "disagreements", "margin"}
    assert len(doc["code"]["bits"]) >= 28
    diagnostics = doc["diagnostics"]
    assert diagnostics["reference_px"] == [0.0, 0.0]
    assert diagnostics["px_per_mm"] == pytest.approx(100.0, rel=1e-3)
    assert diagnostics["position_u_nm"] > 0
    assert diagnostics["ruler"] == "ruler-250"


def test_bright_marks_are_read_as_such() -> None:
    # chrome marks on dark glass: the same ruler seen in negative, described as such
    image, truth = render_ruler(
        pose_for_center_px(320, 240, rotation_deg=-20.0), anchor_mm=88.0, rng=np.random.default_rng(2)
    )
    negative = np.ascontiguousarray(255 - image)
    m = measure_ruler(negative, RulerParams(ruler=RulerSpec(marks="bright")))
    assert abs(m.position_mm - truth.position_mm) * PX_PER_MM <= 0.006
    with pytest.raises(MeasurementError):
        measure_ruler(negative)  # read as dark marks: graduations between the lines, the code inverted


@pytest.mark.parametrize("noise_seed", [1, 2])
def test_a_ruler_end_cutting_the_windows_obliquely_does_not_pull_the_position(noise_seed: int) -> None:
    # the ruler's start crosses the frame at 20 deg to the lines' tips (hard preset): the windows it
    # cuts have too much contrast left to be taken for the bare ruler, and read 0.11-0.13 px off until
    # the code's graduation number puts the end in the frame and the correction is fitted without them
    pose = Pose(x_mm=-0.63, y_mm=0.11, rotation_deg=-161.16, tilt_x_deg=-0.06, tilt_y_deg=0.24)
    image, truth = render_ruler(pose, anchor_mm=2.49, preset="hard", rng=np.random.default_rng(noise_seed))
    m = measure_ruler(image)
    position, offset, _ = _errors(m, truth)
    u_px = m.extra["position_u_nm"] * 1e-6 * truth.px_per_mm
    assert abs(position) <= 0.03, position
    assert abs(position) <= 5 * u_px, (position, u_px)
    assert abs(offset) <= 0.4, offset
    assert m.extra["windows"]["cut_by_end"] > 0
