"""The calibrated parameter set: one versioned JSON document, written by ``identify`` and read back by
``load_kinematics``, the CLI's ``--json`` and the report (format: CALIBRATION.md)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from station._pydantic import problems
from station.calibration._observations import CalibrationError, CameraModel
from station.kinematics import DHRow, Kinematics

SCHEMA_VERSION = 1
"""Version of the JSON document; ``load`` refuses other versions."""


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class DHRowModel(_Model):
    """One modified DH row (mm, deg)."""

    alpha_deg: float
    a_mm: float
    d_mm: float
    theta_offset_deg: float
    beta_deg: float = 0.0

    @classmethod
    def of(cls, row: DHRow) -> DHRowModel:
        return cls(
            alpha_deg=row.alpha_deg,
            a_mm=row.a_mm,
            d_mm=row.d_mm,
            theta_offset_deg=row.theta_offset_deg,
            beta_deg=row.beta_deg,
        )

    def row(self) -> DHRow:
        return DHRow(self.alpha_deg, self.a_mm, self.d_mm, self.theta_offset_deg, self.beta_deg)


class CameraModelModel(_Model):
    """The camera's intrinsics the fit used (px, mm)."""

    focal_px: float
    principal_px: tuple[float, float]
    width: int
    height: int
    working_distance_mm: float

    @classmethod
    def of(cls, camera: CameraModel) -> CameraModelModel:
        return cls(
            focal_px=camera.focal_px,
            principal_px=camera.principal_px,
            width=camera.width,
            height=camera.height,
            working_distance_mm=camera.working_distance_mm,
        )

    def camera(self) -> CameraModel:
        return CameraModel(
            self.focal_px, self.principal_px, self.width, self.height, self.working_distance_mm
        )


class ParameterEstimate(_Model):
    """One parameter: its nominal value, the estimate, its standard deviation and 95 % interval.

    ``identified`` False: the parameter stays at ``nominal`` (structural, or the data do not determine
    it); ``sigma`` and ``interval`` are then None.
    """

    name: str
    unit: str
    nominal: float
    estimate: float
    sigma: float | None = None
    interval: tuple[float, float] | None = None
    identified: bool
    structural: bool = False


class ResidualSummary(_Model):
    """Residuals of a set of observations (mm): image (at the focal plane) and the sensor's reading."""

    n: int
    rms_xy_mm: float
    max_xy_mm: float
    n_z: int = 0
    rms_z_mm: float | None = None
    max_z_mm: float | None = None
    xy_um: list[float] | None = Field(
        default=None,
        description="each observation's image residual (µm, the in-plane distance), in observation order",
    )
    z_um: list[float] | None = Field(
        default=None, description="each sensor reading's residual (µm, measured minus predicted)"
    )


class DeficiencyModel(_Model):
    """A parameter the data cannot determine, as the combination of others it trades with."""

    name: str
    combination: dict[str, float]
    residual: float
    reason: str = ""


class IdentifiabilityModel(_Model):
    """The identifiability analysis at nominal (see ``analyse_identifiability``)."""

    rcond: float
    singular_values: list[float]
    null_dimension: int
    structural: list[DeficiencyModel]
    structural_verified: bool
    deficient: list[str] = Field(
        description="what this data set fails to determine beyond the structural list"
    )
    dropped: list[DeficiencyModel]


class RulerResidualSummary(_Model):
    """Residuals of a set of ruler frames: ``s`` and ``t`` under the reference pixel (mm), the image
    scale (ppm) and the sensor's reading (mm)."""

    n: int
    rms_st_mm: float
    max_st_mm: float
    n_scale: int
    rms_scale_ppm: float | None
    n_z: int
    rms_z_mm: float | None


RELATIVE_ERROR_MEANS = (
    "near the artifacts: the mean in-plane distance (um) between two held-out configurations' positions of "
    "one crossing (the same point: ideally 0), camera turns and joint solutions apart; a model wrong in "
    "its lengths can still bring them together"
)
ABSOLUTE_ERROR_MEANS = (
    "along the rulers: the mean magnitude (um) of the arm's predicted displacement between two held-out "
    "frames of one ruler, 10 mm or more apart, minus the ruler's reading of it (lengths up to the "
    "ruler's 250 mm, which the crossings do not constrain); floor: what the fitted frames' scatter "
    "(the arm's repeatability and the measurement) leaves"
)


class CrossValidation(_Model):
    """The fit's residuals on configurations held out of it, and the relative error on their pairs."""

    held_out_configurations: list[int]
    n_observations: int
    before: ResidualSummary | None = None
    after: ResidualSummary | None = None
    relative_error_um: dict[str, float] = Field(default_factory=dict, description=RELATIVE_ERROR_MEANS)
    n_ruler_observations: int = Field(0, description="held-out ruler frames")
    absolute_error_um: dict[str, float] = Field(
        default_factory=dict,
        description=f"'before', 'after', 'floor' (um): {ABSOLUTE_ERROR_MEANS}",
    )
    absolute_pairs: int = Field(0, description="pairs of held-out ruler frames the absolute error averages")
    measures: dict[str, str] = Field(
        default_factory=dict, description="what each error above measures, and over which region"
    )


class Magnification(_Model):
    """The camera's image scale at the capture plane, as the rulers' calibrated pitch measured it."""

    px_per_mm: float = Field(description="the estimate, px/mm")
    nominal_px_per_mm: float = Field(description="what the camera model said before, px/mm")
    sigma: float | None = Field(description="standard uncertainty, px/mm")
    interval: tuple[float, float] | None = Field(description="95 % interval, px/mm")
    relative_to_nominal: float = Field(description="estimate / nominal - 1")
    sensor_z_mm: float = Field(description="the sensor mount's offset along the optical axis, as fitted")
    source: str = Field("ruler", description="where the scale comes from: the rulers' certificates")


class FitSummary(_Model):
    """The optimiser's outcome."""

    method: str
    evaluations: int
    status: int
    message: str = ""
    observations: int
    residuals: int
    dof: int
    s2: float = Field(description="the weighted residuals' variance factor; covariance = s2 (J^T J)^-1")
    loss: str = Field("linear", description="the fit's loss: linear (least squares) or a robust one")
    f_scale: float | None = Field(None, description="a robust loss's scale (sigmas)")
    downweighted: int = Field(0, description="residuals weighing less than half (beyond the loss's scale)")


class CalibrationResult(_Model):
    """A calibrated parameter set (mm, deg), versioned."""

    schema_version: int = SCHEMA_VERSION
    software_version: str
    created: str = Field(description="ISO 8601, UTC")
    nominal_dh: list[DHRowModel]
    calibrated_dh: list[DHRowModel]
    nominal_tool: list[list[float]] = Field(description="4x4 camera frame in the flange frame, nominal")
    calibrated_tool: list[list[float]] = Field(description="4x4 camera frame in the flange frame, calibrated")
    camera: CameraModelModel = Field(description="the camera model to use with this calibration")
    sensor_mount: list[list[float]] = Field(description="4x4 sensor frame in the camera frame; beam along +z")
    parameters: list[ParameterEstimate]
    identified_count: int
    condition_number: float
    unidentifiable: list[str]
    identifiability: IdentifiabilityModel
    residuals: dict[str, ResidualSummary] = Field(description="'before' (nominal) and 'after' (calibrated)")
    cross_validation: CrossValidation
    fit: FitSummary
    sigmas_mm: dict[str, float]
    magnification: Magnification | None = Field(
        None,
        description="the camera's scale, identified from ruler frames (then ``camera`` and ``sensor_mount`` "
        "are the calibrated ones); None when the camera model was taken as known",
    )
    ruler_residuals: dict[str, RulerResidualSummary] | None = Field(
        None, description="the ruler frames' residuals, 'before' (nominal) and 'after' (calibrated)"
    )

    def kinematics(self) -> Kinematics:
        """The calibrated arm with the camera as the tool."""
        return Kinematics([r.row() for r in self.calibrated_dh], tool=np.asarray(self.calibrated_tool))

    def nominal_kinematics(self) -> Kinematics:
        """The nominal arm with the nominal camera transform (the 'before')."""
        return Kinematics([r.row() for r in self.nominal_dh], tool=np.asarray(self.nominal_tool))

    def parameter(self, name: str) -> ParameterEstimate:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"no parameter {name!r}; the result has {[p.name for p in self.parameters]}")

    def to_json(self) -> str:
        return self.model_dump_json(indent=2)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the JSON document (UTF-8) and return its path."""
        p = Path(path)
        p.write_text(self.to_json() + "\n", encoding="utf-8")
        return p

    @classmethod
    def from_json(cls, text: str, *, source: str = "calibration JSON") -> CalibrationResult:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise CalibrationError(
                f"{source} is not JSON ({exc}); pass a file written by CalibrationResult.save"
            ) from exc
        if not isinstance(data, dict):
            raise CalibrationError(f"{source} must be a JSON object, got {type(data).__name__}")
        version = data.get("schema_version")
        if version != SCHEMA_VERSION:
            raise CalibrationError(
                f"{source} has schema_version {version!r}; this software reads version {SCHEMA_VERSION}:"
                " re-run the identification (station calibrate SESSION) with this version"
            )
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise CalibrationError(f"{source} is not a valid calibration result: {problems(exc)}") from exc

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CalibrationResult:
        """Read a document written by :meth:`save`."""
        p = Path(path)
        try:
            text = p.read_text(encoding="utf-8")
        except OSError as exc:
            raise CalibrationError(f"cannot read the calibration file {p}: {exc.strerror or exc}") from exc
        return cls.from_json(text, source=str(p))


def load_kinematics(path: str | os.PathLike[str]) -> Kinematics:
    """The calibrated arm, camera as the tool, from a calibration result's JSON file.

    Raises
    ------
    CalibrationError
        (a ``ValueError``) for a missing, unreadable or invalid file, or one of another schema version.
    """
    return CalibrationResult.load(path).kinematics()


__all__ = [
    "SCHEMA_VERSION",
    "CalibrationResult",
    "CrossValidation",
    "DHRowModel",
    "DeficiencyModel",
    "FitSummary",
    "IdentifiabilityModel",
    "Magnification",
    "ParameterEstimate",
    "ResidualSummary",
    "RulerResidualSummary",
    "load_kinematics",
]
