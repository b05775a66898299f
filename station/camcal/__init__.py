"""Camera calibration, pure: the target, its detection in a view, the intrinsics and the scale check.

No devices, no record: functions over images and the target's known geometry, which a session kind
(``station run camera-calibration``) calls. ``TARGET.md`` in this package is the target's design note.
"""

from station.camcal._calibrate import FitOptions, calibrate_intrinsics
from station.camcal._detect import (
    EDGE_MARGIN_PX,
    MIN_CORNERS,
    REFINE_SIGMA_PX,
    TargetDetection,
    detect_target,
    refine_corners,
)
from station.camcal._errors import (
    CalibrationFitError,
    CameraCalibrationError,
    ScaleCheckError,
    TargetNotFoundError,
    TooFewViewsError,
)
from station.camcal._follow import follow_target
from station.camcal._heights import HeightScale, SensorReading, height_scale
from station.camcal._result import AGREE_SIGMA, FocalScale, IntrinsicsCalibration, ViewDiagnostics
from station.camcal._scale import SCALE_CHECK_LIMIT, ScaleCheck, check_scale, distance_from_sensor
from station.camcal._target import DICTIONARIES, STANDARD_TARGET, CharucoTarget, TargetCertificate
from station.camcal._views import ViewSpec, plan_views, rotation_about

__all__ = [
    "AGREE_SIGMA",
    "DICTIONARIES",
    "EDGE_MARGIN_PX",
    "MIN_CORNERS",
    "REFINE_SIGMA_PX",
    "SCALE_CHECK_LIMIT",
    "STANDARD_TARGET",
    "CalibrationFitError",
    "CameraCalibrationError",
    "CharucoTarget",
    "FitOptions",
    "FocalScale",
    "HeightScale",
    "IntrinsicsCalibration",
    "ScaleCheck",
    "ScaleCheckError",
    "SensorReading",
    "TargetCertificate",
    "TargetDetection",
    "TargetNotFoundError",
    "TooFewViewsError",
    "ViewDiagnostics",
    "ViewSpec",
    "calibrate_intrinsics",
    "check_scale",
    "detect_target",
    "distance_from_sensor",
    "follow_target",
    "height_scale",
    "plan_views",
    "refine_corners",
    "rotation_about",
]
