"""Kinematic calibration of the arm from the station's relative measurements (pure, offline).

See CALIBRATION.md in this package for the model, the parameter names, the structural list and the JSON
format.
"""

from station.calibration._compensation import compensated_joints, compensated_steps, joint_steps
from station.calibration._identifiability import (
    REPORTED_NAMES,
    STRUCTURAL,
    Deficiency,
    IdentifiabilityReport,
    analyse_identifiability,
    reported_name,
)
from station.calibration._identify import (
    LOSSES,
    analyse,
    identify,
    initial_artifacts,
    residual_summary,
    robust_weights,
)
from station.calibration._metric import crossing_positions, pair_errors_um, relative_error_um
from station.calibration._model import CalibrationModel, Sigmas
from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    CameraModel,
    Observation,
    ObservationArrays,
    observation_arrays,
)
from station.calibration._result import (
    SCHEMA_VERSION,
    CalibrationResult,
    FitSummary,
    ParameterEstimate,
    ResidualSummary,
)
from station.calibration._truth import equivalent_errors, true_values

__all__ = [
    "LOSSES",
    "REPORTED_NAMES",
    "SCHEMA_VERSION",
    "STRUCTURAL",
    "CalibrationError",
    "CalibrationModel",
    "CalibrationResult",
    "CalibrationSetup",
    "CameraModel",
    "Deficiency",
    "FitSummary",
    "IdentifiabilityReport",
    "Observation",
    "ObservationArrays",
    "ParameterEstimate",
    "ResidualSummary",
    "Sigmas",
    "analyse",
    "analyse_identifiability",
    "compensated_joints",
    "compensated_steps",
    "crossing_positions",
    "equivalent_errors",
    "identify",
    "initial_artifacts",
    "joint_steps",
    "observation_arrays",
    "pair_errors_um",
    "relative_error_um",
    "reported_name",
    "residual_summary",
    "robust_weights",
    "true_values",
]
