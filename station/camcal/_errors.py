"""Camera-calibration errors: each says what is wrong and what to do; ``code`` is stable."""

from __future__ import annotations


class CameraCalibrationError(ValueError):
    """A camera calibration could not be done. ``code`` is a stable machine-readable reason."""

    code = "camera_calibration_failed"


class TargetNotFoundError(CameraCalibrationError):
    """Too few of the target's corners were found in a view."""

    code = "target_not_found"


class TooFewViewsError(CameraCalibrationError):
    """The views cannot determine the camera: too few, too few corners, or all alike."""

    code = "too_few_views"


class CalibrationFitError(CameraCalibrationError):
    """The fit failed or gave an implausible camera (OpenCV's error, or a result beyond the bounds)."""

    code = "calibration_fit_failed"


class ScaleCheckError(CameraCalibrationError):
    """The scale check's inputs are out of range (a distance, width or tolerance that cannot be)."""

    code = "bad_scale_check_input"
