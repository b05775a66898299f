"""The scale check (camera model + distance against the groove's width) and the focal scale from heights."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.artifact import CameraSpec, pose_for_center_px, render
from station.camcal import (
    SCALE_CHECK_LIMIT,
    ScaleCheckError,
    SensorReading,
    TooFewViewsError,
    check_scale,
    distance_from_sensor,
    height_scale,
)
from station.camera_model import CameraIntrinsics
from station.vision import NOMINAL_GROOVE_WIDTH_MM, measure

CAMERA = CameraSpec()  # the cross renderer's camera: an ideal pinhole, f = 100 px/mm x 68 mm
DRAWING = (-0.0508, 0.0)  # +0/-0.002 in
CALIBRATED = (-0.004, 0.004)  # a scale calibration's width, +/-2u with u = 2 um


@pytest.fixture(scope="module")
def capture():
    image, _ = render(pose_for_center_px(350.0, 210.0, rotation_deg=6.0), rng=np.random.default_rng(9))
    return measure(image)


def _model(focal_error: float) -> CameraIntrinsics:
    K = CAMERA.matrix().copy()
    K[0, 0] *= 1 + focal_error
    K[1, 1] *= 1 + focal_error
    return CameraIntrinsics(K, np.zeros(5), (CAMERA.width, CAMERA.height), sigma={"fx": 0.7, "fy": 0.7})


def _check(capture, focal_error: float, tolerance=CALIBRATED, distance_mm: float = 68.0):
    return check_scale(
        _model(focal_error),
        distance_mm=distance_mm,
        groove_width_px=capture.groove_width_px,
        groove_width_mm=NOMINAL_GROOVE_WIDTH_MM,
        width_tolerance_mm=tolerance,
        rotation_deg=capture.rotation_deg,
        center_px=capture.center_px,
    )


def test_the_right_model_agrees_with_the_groove(capture) -> None:
    check = _check(capture, 0.0)
    assert check.passes()
    assert check.problem() is None
    np.testing.assert_allclose(check.implied_width_mm, NOMINAL_GROOVE_WIDTH_MM, rtol=3e-4)
    assert check.u_rel == pytest.approx(math.hypot(0.7 / 6800, 0.02 / min(capture.groove_width_px)), rel=1e-6)


@pytest.mark.parametrize("focal_error", [0.01, -0.01])
def test_a_1pct_focal_error_fails_against_a_calibrated_width(capture, focal_error: float) -> None:
    check = _check(capture, focal_error)
    assert not check.passes(SCALE_CHECK_LIMIT)
    assert abs(check.disagreement) > 0.004  # 1 % less the interval's half-width (0.5 %)
    assert math.copysign(1, check.disagreement) == -math.copysign(1, focal_error)
    message = check.problem()
    assert message is not None
    assert "station run camera-calibration" in message
    assert "station teach sensor-mount" in message


def test_with_the_drawings_tolerance_only_a_short_focal_length_shows(capture) -> None:
    # A groove can be up to 6.4 % narrower than drawn: a focal length 1 % too long looks like a narrow
    # groove and passes; 1 % too short makes it wider than drawn, which no groove can be.
    assert _check(capture, 0.01, DRAWING).passes()
    too_short = _check(capture, -0.01, DRAWING)
    assert not too_short.passes()
    assert too_short.disagreement == pytest.approx(0.01, abs=0.001)


def test_a_wrong_distance_is_caught_like_a_wrong_focal_length(capture) -> None:
    assert not _check(capture, 0.0, distance_mm=68.0 * 1.01).passes()  # a sensor mount 0.7 mm off
    assert _check(capture, 0.0, distance_mm=68.0 * 1.001).passes()  # within 0.2 %


def test_distortion_sets_the_local_scale() -> None:
    # Radial distortion k1: at radius r (normalised) a length across the radius is magnified 1 + 3 k1 r^2,
    # along the circle 1 + k1 r^2. A crossing on the x axis: the vertical groove's width lies radially.
    k1 = 30.0
    K = CAMERA.matrix()
    model = CameraIntrinsics(K, np.array([k1, 0, 0, 0, 0]), (640, 480))
    r = 0.04
    center = (K[0, 2] + r * (1 + k1 * r * r) * K[0, 0], K[1, 2])
    nominal_px = K[0, 0] * NOMINAL_GROOVE_WIDTH_MM / 68.0
    check = check_scale(
        model,
        distance_mm=68.0,
        groove_width_px=(nominal_px, nominal_px),
        groove_width_mm=NOMINAL_GROOVE_WIDTH_MM,
        center_px=center,
    )
    h, v = check.expected_px
    assert h == pytest.approx(nominal_px * (1 + k1 * r * r), rel=2e-4)
    assert v == pytest.approx(nominal_px * (1 + 3 * k1 * r * r), rel=2e-4)
    undistorted = check_scale(
        model,
        distance_mm=68.0,
        groove_width_px=(nominal_px, nominal_px),
        groove_width_mm=NOMINAL_GROOVE_WIDTH_MM,
        center_px=center,
        undistorted=True,
    )
    assert undistorted.expected_px == pytest.approx((nominal_px, nominal_px), rel=1e-12)


def test_distance_from_the_sensor() -> None:
    mount = np.eye(4)
    mount[:3, 3] = (30.0, 0.0, -2.5)
    assert distance_from_sensor(70.5, mount) == pytest.approx(68.0)
    with pytest.raises(ScaleCheckError, match="positive distance"):
        distance_from_sensor(-1.0, mount)
    with pytest.raises(ScaleCheckError, match="4x4"):
        distance_from_sensor(70.0, np.eye(3))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"distance_mm": 0.0}, "must all be positive"),
        ({"groove_width_px": (80.0,)}, "two finite groove widths"),
        ({"groove_width_px": (80.0, math.nan)}, "two finite groove widths"),
        ({"width_tolerance_mm": (0.0, -0.1)}, "lower end is below its upper"),
        ({"distance_u_mm": -1.0}, "uncertainties must be >= 0"),
    ],
)
def test_bad_scale_check_inputs(kwargs: dict[str, object], message: str) -> None:
    args: dict[str, object] = {
        "distance_mm": 68.0,
        "groove_width_px": (79.4, 79.4),
        "groove_width_mm": NOMINAL_GROOVE_WIDTH_MM,
    }
    args.update(kwargs)
    with pytest.raises(ScaleCheckError, match=message):
        check_scale(_model(0.0), **args)  # type: ignore[arg-type]


def test_height_scale_reads_the_focal_error_off_the_fitted_distances() -> None:
    kappa = 1.012  # the fit's focal length 1.2 % long makes every distance 1.2 % long
    rng = np.random.default_rng(0)
    readings: list[SensorReading | None] = []
    distances: list[float] = []
    tilts: list[float] = []
    for group, offset in ((0, 3.1), (1, -0.4)):
        for h in (-0.6, -0.3, 0.0, 0.3, 0.6):
            readings.append(SensorReading(group, 70.0 + h + offset))
            distances.append(kappa * (68.0 + h) + rng.normal(0, 1e-4))
            tilts.append(0.3)
    readings.append(SensorReading(2, 75.0))  # a tilted view: left out
    distances.append(50.0)
    tilts.append(12.0)
    readings.append(None)
    distances.append(68.0)
    tilts.append(0.0)
    scale = height_scale(distances, tilts, readings, pitch_u_rel=1e-5, sensor_scale_u_rel=2e-4)
    assert scale.kappa == pytest.approx(kappa, abs=2e-4)
    assert (scale.views, scale.groups) == (10, 2)
    assert scale.range_mm == pytest.approx(1.2)
    assert scale.u_rel >= 2e-4  # the sensor's scale is carried
    with pytest.raises(TooFewViewsError, match="no orientation has two views square"):
        height_scale([68.0, 68.5], [5.0, 5.0], [SensorReading(0, 70.0), SensorReading(0, 70.5)])
    with pytest.raises(ValueError, match="finite"):
        SensorReading(0, math.inf)


def test_an_even_bias_of_the_blur_is_taken_out_of_the_scatter_not_the_slope() -> None:
    # the blur biases the fitted distance evenly about focus (2 um at +/-1.5 mm): square views at
    # -1.5, 0, +1.5 mm, the sensor's noise 0.6 um
    kappa, rng = 1.003, np.random.default_rng(1)
    readings: list[SensorReading | None] = []
    distances: list[float] = []
    for group in range(4):
        for h in [0.0] + [-1.5, 1.5] * 6:
            readings.append(SensorReading(group, 66.0 + h + 0.1 * group + rng.normal(0, 6e-4)))
            distances.append(kappa * (68.0 + h) + 0.002 * (h / 1.5) ** 2)
    scale = height_scale(distances, [0.0] * len(distances), readings)
    assert scale.kappa == pytest.approx(kappa, abs=5e-5)
    assert scale.curvature_um_per_mm2 == pytest.approx(2.0 / 1.5**2, abs=0.3)
    assert scale.residual_um < 1.0  # the sensor's noise, not the bias (0.9 um rms without the term)
    # two heights a turn: no room for the term, none fitted
    two = [
        i for i, r in enumerate(readings) if r is not None and abs(r.distance_mm - 66.0 - 0.1 * r.group) > 1
    ]
    only = height_scale([distances[i] for i in two], [0.0] * len(two), [readings[i] for i in two])
    assert only.curvature_um_per_mm2 is None
