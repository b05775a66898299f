"""The ``calibration`` kind's results: the relative error (um) before and after, the identified
parameters, and the parts of the versioned calibration document (``station.calibration``) a report shows.

The residual and fit summaries are the calibration document's own models (``station.calibration``).
"""

from __future__ import annotations

from typing import Any

from pydantic import Field

from station.calibration import FitSummary, ResidualSummary
from station.plans._results import Check, ResultsModel


class RelativeError(ResultsModel):
    """The relative error (um): the mean in-plane distance between held-out configurations' crossings of one
    placement, with the nominal (``before``) and the calibrated (``after``) model, and the ``floor`` (what
    repeatability and noise leave). Any may be missing (too few held-out pairs, no return captures)."""

    before: float | None = None
    after: float | None = None
    floor: float | None = None


class AbsoluteError(ResultsModel):
    """The error along the rulers (um): the mean magnitude of the arm's predicted displacement between two
    held-out ruler frames 10 mm or more apart minus the ruler's reading of it, with the nominal
    (``before``) and the calibrated (``after``) model, and the ``floor`` the fitted frames' scatter leaves."""

    before: float | None = None
    after: float | None = None
    floor: float | None = None


class MagnificationEstimate(ResultsModel):
    """The camera's image scale at the capture plane as the rulers' certified pitch gives it (px/mm), its
    standard uncertainty and 95 % interval, the nominal it replaces, and the sensor mount's fitted offset
    along the optical axis (mm)."""

    px_per_mm: float
    sigma: float | None = None
    interval: tuple[float, float] | None = None
    nominal_px_per_mm: float
    relative_to_nominal: float
    sensor_z_mm: float
    sensor_z_sigma_mm: float | None = None
    source: str = "ruler"


class RulerScaleCalibration(ResultsModel):
    """The groove width (mm) the crossings' measured widths give at the rulers' magnification, its
    standard uncertainty, and the session: the station's scale calibration from the rulers."""

    groove_width_mm: float
    u_mm: float
    source: str = "ruler"
    session_id: str | int | None = None


class FigureMeaning(ResultsModel):
    """What one of the results' figures measures, and over which region of the cell it holds."""

    meaning: str
    region: str


class CalibrationParameter(ResultsModel):
    """One model parameter: nominal and estimate in ``unit``; ``sigma`` and ``interval`` (95 %) only when
    identified; ``structural``: no pose set identifies it (it stays at nominal)."""

    name: str
    unit: str = ""
    nominal: float
    estimate: float
    interval: tuple[float, float] | None = None
    sigma: float | None = None
    identified: bool
    structural: bool = False


class Deficiency(ResultsModel):
    """A parameter (or combination) the data cannot determine, as the combination of others it trades
    with (``{other: k}`` in natural units) and how far from exact (``residual``; 0 = indistinguishable)."""

    name: str
    combination: dict[str, float] = Field(default_factory=dict)
    residual: float | None = None
    reason: str = ""


class Identifiability(ResultsModel):
    """The SVD of the column-scaled Jacobian of all parameters (singular values descending), the
    structural list, and what this pose set fails to determine (``deficient``, ``dropped``)."""

    rcond: float
    singular_values: list[float] = Field(default_factory=list)
    null_dimension: int
    structural: list[Deficiency] = Field(default_factory=list)
    structural_verified: bool | None = None
    deficient: list[str] = Field(default_factory=list)
    dropped: list[Deficiency] = Field(default_factory=list)


class CrossValidation(ResultsModel):
    held_out_configurations: list[int] = Field(default_factory=list)
    n_observations: int = 0
    before: ResidualSummary | None = None
    after: ResidualSummary | None = None


class CalibrationDocument(ResultsModel):
    """The parts of the versioned ``CalibrationResult`` JSON (``station.calibration``) a report shows."""

    schema_version: int | None = None
    software_version: str | None = None
    created: str | None = None
    identifiability: Identifiability
    residuals: dict[str, ResidualSummary] = Field(default_factory=dict)
    cross_validation: CrossValidation | None = None
    fit: FitSummary | None = None
    sigmas_mm: dict[str, float] = Field(default_factory=dict)


class CalibrationResults(ResultsModel):
    """A calibration session's results (``station.kinds.calibration.analysis.analyse_calibration``)."""

    relative_error_um: RelativeError
    floor_source: str | None = None
    condition_number: float
    unidentifiable: list[str] = Field(default_factory=list)
    identified_count: int
    parameters: list[CalibrationParameter]
    observations: int | None = None
    configurations: int | None = None
    placements: list[int] = Field(default_factory=list)
    held_out_configurations: list[int] = Field(default_factory=list)
    planned_configurations: int | None = None
    left_out: list[Any] = Field(default_factory=list)
    calibration: CalibrationDocument
    checks: list[Check] = Field(default_factory=list)
    absolute_error_um: AbsoluteError | None = Field(None, description="with rulers: the error along them")
    absolute_pairs: int | None = Field(
        None, description="held-out ruler frame pairs the absolute error averages"
    )
    ruler_frames: int | None = Field(None, description="ruler frames measured and used")
    rulers: list[int] | None = Field(None, description="the cell's rulers those frames are of")
    magnification: MagnificationEstimate | None = None
    magnification_check: Check | None = Field(
        None, description="the magnification against the groove widths measured (also in checks)"
    )
    scale_calibration: RulerScaleCalibration | None = Field(
        None, description="with rulers: the station's scale calibration they give (written if it passed)"
    )
    measures: dict[str, FigureMeaning] = Field(
        default_factory=dict, description="what each figure above measures and over which region"
    )
