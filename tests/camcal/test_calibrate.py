"""Calibrating the camera from views like a session's, against the twin's true lens."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sim.lens import nominal_intrinsics, true_intrinsics
from sim.target import F4_DEFOCUS_PX_PER_MM, TargetPose, render_target
from sim.target_sensor import sensor_distance
from station.camcal import (
    CalibrationFitError,
    FitOptions,
    IntrinsicsCalibration,
    SensorReading,
    TargetDetection,
    TooFewViewsError,
    calibrate_intrinsics,
    detect_target,
    plan_views,
)
from station.camera_model import CameraIntrinsics

MOUNT = np.eye(4)
MOUNT[:3, 3] = (30.0, 0.0, 0.0)
# A small session: 2 square turns at 3 heights (the sensor reads each) and 8 views tilted 12 deg.
VIEWS = plan_views(
    square_turns_deg=(0.0, 90.0),
    heights_mm=(-0.6, 0.0, 0.6),
    square_passes=1,
    azimuths=4,
    tilted_turns_deg=(0.0, 90.0),
)
TRUTH = true_intrinsics(1)

Session = tuple[list[TargetDetection], list[SensorReading | None]]


def _session(defocus_px_per_mm: float) -> Session:
    rng = np.random.default_rng(23)
    detections, readings = [], []
    for view in VIEWS:
        pose = TargetPose.from_view(view)
        image, _ = render_target(pose, intrinsics=TRUTH, defocus_px_per_mm=defocus_px_per_mm, rng=rng)
        detections.append(detect_target(image))
        square = view.tilt_deg == 0.0
        readings.append(SensorReading(view.group, sensor_distance(pose, MOUNT, rng=rng)) if square else None)
    return detections, readings


@pytest.fixture(scope="module")
def in_focus() -> Session:
    return _session(0.0)


@pytest.fixture(scope="module")
def f4() -> Session:
    return _session(F4_DEFOCUS_PX_PER_MM)


def _errors(cal: IntrinsicsCalibration) -> tuple[float, float, float, float]:
    m, K = cal.intrinsics, TRUTH.camera_matrix
    return (
        m.fx / K[0, 0] - 1,
        m.fy / K[1, 1] - 1,
        m.principal_point[0] - K[0, 2],
        m.principal_point[1] - K[1, 2],
    )


@pytest.mark.slow
def test_in_focus_views_give_the_focal_length_to_005pct_and_the_centre_to_1px(in_focus: Session) -> None:
    detections, readings = in_focus
    # Everything sharp (no defocus): Zhang's method alone meets issue 23's bounds...
    cal = calibrate_intrinsics(detections, guess=nominal_intrinsics())
    fx, fy, cx, cy = _errors(cal)
    assert abs(fx) < 5e-4
    assert abs(fy) < 5e-4
    assert abs(cx) < 1.0
    assert abs(cy) < 1.0
    sigma = cal.intrinsics.sigma  # and its uncertainties say so (errors within 3 sigma)
    assert abs(fx) < 3 * sigma["fx"] / cal.intrinsics.fx
    assert abs(cx) < 3 * sigma["cx"]
    assert abs(cy) < 3 * sigma["cy"]
    assert cal.focal.source == "tilted views"
    assert cal.rms_px < 0.02
    assert abs(cal.intrinsics.coefficient("k1") - TRUTH.coefficient("k1")) < 0.05 * abs(
        TRUTH.coefficient("k1")
    )
    assert cal.intrinsics.image_size == (640, 480)
    assert cal.intrinsics.source["views"] == len(VIEWS)
    assert [v.tilt_deg > 10 for v in cal.views] == [v.tilt_deg > 0 for v in VIEWS]
    # ...and the heights agree with it: no warning, the focal length from them within their uncertainty.
    with_heights = calibrate_intrinsics(detections, guess=nominal_intrinsics(), readings=readings)
    assert with_heights.focal.source == "heights"
    assert with_heights.warnings() == []
    hx = _errors(with_heights)[0]
    assert abs(hx) < 3 * with_heights.focal.u_rel
    assert abs(_errors(with_heights)[2]) < 1.0


@pytest.mark.slow
def test_defocus_biases_tilted_views_and_the_heights_catch_it(f4: Session) -> None:
    detections, readings = f4
    cal = calibrate_intrinsics(detections, guess=nominal_intrinsics(), readings=readings)
    tilted_error = cal.focal.tilted_fx_px / TRUTH.fx - 1
    # Zhang's method alone: off by far more than OpenCV's uncertainty says (the blur across tilted views)...
    assert abs(tilted_error) > 4 * cal.focal.tilted_u_rel
    assert cal.focal.source == "heights"
    assert cal.focal.disagreement_sigma is not None
    assert cal.focal.disagreement_sigma > 3
    assert any("the heights' is used" in w for w in cal.warnings())
    # ...while the calibration's focal length and its uncertainty hold the truth.
    fx, fy, cx, cy = _errors(cal)
    u = cal.focal.u_rel
    assert abs(fx) < 3 * u
    assert abs(fy) < 3 * u
    assert abs(fx) < abs(tilted_error) / 3
    assert abs(cx) < 3 * cal.intrinsics.sigma["cx"]
    assert abs(cy) < 3 * cal.intrinsics.sigma["cy"]
    # Six square views cannot give 0.05 %: the calibration says so, and what to do.
    problems = cal.problems()
    assert any(
        "fx is known to" in p and "more square views over a wider span of heights" in p for p in problems
    )
    # Without readings the tilted views' focal length is all there is, and that is a problem by default.
    alone = calibrate_intrinsics(detections, guess=nominal_intrinsics())
    assert alone.focal.source == "tilted views"
    assert any("tilted views alone" in p for p in alone.problems())
    assert not any("tilted views alone" in p for p in alone.problems(require_heights=False))


@pytest.mark.slow
def test_a_misdetected_corner_is_left_out_and_counted(in_focus: Session) -> None:
    detections, readings = in_focus
    bad = detections[7].corners_px.copy()
    bad[10] += (3.0, -2.0)
    spoiled = [*detections[:7], replace(detections[7], corners_px=bad), *detections[8:]]
    clean = calibrate_intrinsics(detections, guess=nominal_intrinsics(), readings=readings)
    cal = calibrate_intrinsics(spoiled, guess=nominal_intrinsics(), readings=readings)
    assert cal.views[7].dropped == 1
    assert sum(v.dropped for v in cal.views) == 1
    np.testing.assert_allclose(cal.intrinsics.camera_matrix, clean.intrinsics.camera_matrix, rtol=1e-4)


def test_too_few_or_inconsistent_views_are_refused(in_focus: Session) -> None:
    detections, readings = in_focus
    guess = nominal_intrinsics()
    with pytest.raises(TooFewViewsError, match="2 views of the target; a calibration needs at least 3"):
        calibrate_intrinsics(detections[:2], guess=guess)
    other = replace(detections[1], image_size=(1280, 960))
    with pytest.raises(TooFewViewsError, match="different image sizes"):
        calibrate_intrinsics([detections[0], other, detections[2]], guess=guess)
    with pytest.raises(TooFewViewsError, match="starting camera model holds for 1280 x 960"):
        calibrate_intrinsics(
            detections, guess=CameraIntrinsics(guess.camera_matrix, np.zeros(5), (1280, 960))
        )
    with pytest.raises(TooFewViewsError, match="3 sensor readings for 14 views"):
        calibrate_intrinsics(detections, guess=guess, readings=readings[:3])
    only_tilted: list[SensorReading | None] = [None] * len(readings)
    only_tilted[-1] = SensorReading(99, 70.0)  # a tilted view's reading: not usable for the heights
    with pytest.raises(TooFewViewsError, match="take the square views at several heights"):
        calibrate_intrinsics(detections, guess=guess, readings=only_tilted)


def test_a_wrong_nominal_camera_is_refused_not_believed(in_focus: Session) -> None:
    detections, _ = in_focus
    wrong = CameraIntrinsics(
        np.array([[3400.0, 0.0, 319.5], [0.0, 3400.0, 239.5], [0.0, 0.0, 1.0]]), np.zeros(5)
    )
    with pytest.raises(CalibrationFitError, match="from the nominal"):
        calibrate_intrinsics(detections[:8], guess=wrong, options=FitOptions(radial=1))


def test_fit_options_free_what_they_say() -> None:
    assert FitOptions().fitted() == ("fx", "fy", "cx", "cy", "k1")
    assert FitOptions(radial=2, tangential=True).fitted() == ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2")
    with pytest.raises(ValueError, match="radial must be 1, 2 or 3"):
        FitOptions(radial=4)
    with pytest.raises(ValueError, match="outlier_px"):
        FitOptions(outlier_px=math.nan)


@pytest.mark.slow
def test_pose_only_views_enter_the_heights_but_not_the_intrinsics_fit(in_focus: Session) -> None:
    detections, readings = in_focus
    followed = [v.tilt_deg == 0.0 and v.height_mm != 0.0 for v in VIEWS]
    # a followed view's corners spoiled by 0.3 px of noise: the intrinsics' fit must not see them
    rng = np.random.default_rng(4)
    noisy = [
        replace(d, corners_px=d.corners_px + rng.normal(0.0, 0.15, d.corners_px.shape)) if f else d
        for d, f in zip(detections, followed, strict=True)
    ]
    clean = calibrate_intrinsics(detections, guess=nominal_intrinsics(), readings=readings)
    spoiled = calibrate_intrinsics(noisy, guess=nominal_intrinsics(), readings=readings)
    cal = calibrate_intrinsics(noisy, guess=nominal_intrinsics(), readings=readings, pose_only=followed)
    assert [v.pose_only for v in cal.views] == followed
    assert cal.rms_px < 0.02  # the in-focus views' only (the noisy ones re-project at about 0.2 px)
    assert min(v.rms_px for v in cal.views if v.pose_only) > 0.1
    assert spoiled.rms_px > 0.05
    # OpenCV's uncertainties scale with the fit's residual: the noisy views in it inflate them
    assert cal.intrinsics.sigma["cx"] < 0.5 * spoiled.intrinsics.sigma["cx"]
    assert cal.focal.heights is not None
    assert cal.focal.heights.views == clean.focal.heights.views  # type: ignore[union-attr]
    with pytest.raises(TooFewViewsError, match="views in focus"):
        calibrate_intrinsics(detections, guess=nominal_intrinsics(), pose_only=[True] * len(detections))
