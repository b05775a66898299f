"""The ``validation`` kind's results (um where the seed reports um): the rigid, similarity and affine fits
of measured to commanded displacements, each position, the groove width and the gates' checks."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from station.plans._results import Check, ResultsModel

Point = tuple[float, float]


class Fit(ResultsModel):
    """One best fit of commanded to measured displacements, as ``station validate --json`` prints it."""

    mean_um: float
    max_um: float
    rms_um: float | None = None
    scale: float | None = None
    rotation_deg: float | None = None


class Position(ResultsModel):
    """One table position. ``error_*_um`` = measured - fitted commanded, in the measured (artifact) axes;
    no parallelogram error when the positions measured lie on a line (a session stopped early)."""

    index: int
    commanded_um: Point
    measured_um: Point
    error_um: Point
    error_parallelogram_um: Point | None = None


class ScaleCalibration(ResultsModel):
    groove_width_mm: float
    u_mm: float
    session_id: str | int | None = None


class ValidationResults(ResultsModel):
    mean_um: float
    max_um: float
    parallelogram_mean_um: float | None = None
    parallelogram_max_um: float | None = None
    scale: float
    groove_width_mm: float | None
    rigid: Fit
    similarity: Fit
    affine: Fit | None = None
    positions: list[Position] = Field(default_factory=list)
    scale_calibration: ScaleCalibration | None = None
    groove_width_u_mm: float | None = None
    groove_width_used_mm: float | None = None
    approach: str | None = None
    failures: list[dict[str, Any]] = Field(default_factory=list)
    n_positions: int | None = None
    partial: bool | None = None
    checks: list[Check] = Field(default_factory=list)
    artifact: Literal["ruler"] | None = Field(
        None, description="'ruler' when the table carried a ruler (absolute positions); absent: the cross"
    )
    scale_u: float | None = Field(
        None, description="standard uncertainty of ``scale`` (a ruler's: the micrometers against its pitch)"
    )
