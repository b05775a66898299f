"""Kinematic calibration of the arm from the station's relative measurements (pure, offline).

See CALIBRATION.md in this package for the model, the parameter names, the structural list and the JSON
format.
"""

from station.calibration._absolute import (
    MIN_SEPARATION_MM,
    absolute_error_um,
    absolute_floor_um,
    ruler_pair_errors_um,
    ruler_points,
)
from station.calibration._compensation import compensated_joints, compensated_steps, joint_steps
from station.calibration._fit import LOSSES, robust_weights
from station.calibration._identifiability import (
    REPORTED_NAMES,
    STRUCTURAL,
    Deficiency,
    IdentifiabilityReport,
    analyse_identifiability,
    reported_name,
)
from station.calibration._identify import (
    CAMERA_CHOICES,
    analyse,
    identify,
)
from station.calibration._metric import crossing_positions, pair_errors_um, relative_error_um
from station.calibration._model import CalibrationModel, Sigmas
from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    CameraModel,
    Observation,
    ObservationArrays,
    RulerPlacement,
    observation_arrays,
)
from station.calibration._result import (
    SCHEMA_VERSION,
    CalibrationResult,
    FitSummary,
    Magnification,
    ParameterEstimate,
    ResidualSummary,
    RulerResidualSummary,
    load_kinematics,
)
from station.calibration._ruler_observations import RulerArrays, RulerObservation, ruler_arrays
from station.calibration._scale_check import MagnificationCheck, magnification_check
from station.calibration._start import initial_artifacts, initial_rulers
from station.calibration._truth import equivalent_errors, true_values
from station.calibration._validation import residual_summary, ruler_residual_summary

__all__ = [
    "CAMERA_CHOICES",
    "LOSSES",
    "MIN_SEPARATION_MM",
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
    "Magnification",
    "MagnificationCheck",
    "Observation",
    "ObservationArrays",
    "ParameterEstimate",
    "ResidualSummary",
    "RulerArrays",
    "RulerObservation",
    "RulerPlacement",
    "RulerResidualSummary",
    "Sigmas",
    "absolute_error_um",
    "absolute_floor_um",
    "analyse",
    "analyse_identifiability",
    "compensated_joints",
    "compensated_steps",
    "crossing_positions",
    "equivalent_errors",
    "identify",
    "initial_artifacts",
    "initial_rulers",
    "joint_steps",
    "load_kinematics",
    "magnification_check",
    "observation_arrays",
    "pair_errors_um",
    "relative_error_um",
    "reported_name",
    "residual_summary",
    "robust_weights",
    "ruler_arrays",
    "ruler_pair_errors_um",
    "ruler_points",
    "ruler_residual_summary",
    "true_values",
]
