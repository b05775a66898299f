"""The ``camera-calibration`` kind's results: the camera's intrinsics with their standard uncertainties,
the fit's re-projection error, the image size the model holds for, the views used, where the model was
written, and the session's gates."""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.plans._results import Check, ResultsModel


class Estimate(ResultsModel):
    """A fitted intrinsic and its standard uncertainty (1 sigma, OpenCV's ``stdDeviationsIntrinsics``, the
    heights' scale included for the focal lengths); ``sigma`` is None for one held fixed."""

    value: float
    sigma: float | None = None


class CameraCalibrationResults(ResultsModel):
    passed: bool
    fx: Estimate = Field(description="focal length along x (px)")
    fy: Estimate = Field(description="focal length along y (px)")
    cx: Estimate = Field(description="principal point x (px)")
    cy: Estimate = Field(description="principal point y (px)")
    distortion: dict[str, Estimate] = Field(
        default_factory=dict, description="OpenCV's coefficients k1, k2, p1, p2, k3 (fixed ones: sigma None)"
    )
    rms_px: float = Field(description="re-projection error over every corner used (px, root mean square)")
    image_size: tuple[int, int] = Field(description="width, height (px) the model holds for")
    views: int = Field(description="views the fit used")
    views_taken: int = Field(description="views captured")
    corners: int = 0
    focal_source: str = Field("", description="where the focal lengths' scale came from: heights or tilted")
    focal: dict[str, Any] = Field(default_factory=dict)
    camera_model: dict[str, Any] = Field(default_factory=dict, description="the model as written")
    camera_model_file: str | None = Field(
        None, description="where the model was written (a passed session only); None otherwise"
    )
    previous_model_file: str | None = Field(None, description="where the model it replaced was kept")
    problems: list[str] = Field(default_factory=list)
    warnings: list[str] = Field(default_factory=list)
    view_diagnostics: list[dict[str, Any]] = Field(default_factory=list)
    checks: list[Check] = Field(default_factory=list)
