"""Identification: the kinematic errors, tool, artifact and ruler poses (and, with rulers, the camera's
scale) that best explain the captures.

Order of work: (1) the artifacts' and rulers' placements from the captures under the nominal model (a
start, and the "before" fit: nominal kinematics and camera, placements fitted alone); (2)
identifiability at nominal (``analyse_identifiability``): the structural list is verified and left at
nominal, subset selection drops what this data set does not determine; (3)
``scipy.optimize.least_squares`` on the identified subset (central-difference Jacobian, internal units
mm, mrad and 0.1 px/mm); (4) covariance ``s^2 (J^T J)^-1`` with ``s^2`` from the residuals, 95 %
intervals from Student's t; (5) residuals of the configurations held out of the fit, their relative
error (``relative_error_um``, near the artifacts) and, with rulers, their absolute error
(``absolute_error_um``, along the rulers), before and after.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.stats

import station
from station.calibration._absolute import MIN_SEPARATION_MM
from station.calibration._fit import LOSSES, Problem, least_squares, method, robust_weights
from station.calibration._identifiability import (
    STRUCTURAL,
    Deficiency,
    IdentifiabilityReport,
    analyse_identifiability,
    reported_name,
)
from station.calibration._model import CalibrationModel, Sigmas
from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    FloatArray,
    Observation,
    observation_arrays,
)
from station.calibration._result import (
    CalibrationResult,
    CameraModelModel,
    DeficiencyModel,
    DHRowModel,
    FitSummary,
    IdentifiabilityModel,
    Magnification,
    ParameterEstimate,
)
from station.calibration._ruler_observations import RulerObservation, ruler_arrays
from station.calibration._start import initial_artifacts, initial_rulers
from station.calibration._validation import cross_validation, residual_summary, ruler_residual_summary

log = logging.getLogger(__name__)

CAMERA_CHOICES = ("auto", "fixed", "fitted")
"""``camera``: ``fixed`` takes the setup's camera model and sensor mount as known; ``fitted`` identifies
the image scale and the sensor's offset along the optical axis; ``auto`` fits them when there are ruler
frames (the scale then comes from the rulers' calibrated pitch) and keeps them otherwise."""


def _utc_now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def analyse(
    observations: Sequence[Observation],
    setup: CalibrationSetup,
    *,
    sigmas: Sigmas | None = None,
    rcond: float = 1e-5,
) -> IdentifiabilityReport:
    """The identifiability of a data set at nominal, before any fit (see ``analyse_identifiability``).

    The model covers the placements the observations see; the artifacts start where the captures put
    them under the nominal model.
    """
    sig = sigmas or Sigmas()
    model = CalibrationModel(setup, placements=sorted({o.placement for o in observations}), rulers=())
    arrays = observation_arrays(observations, model.placements)
    start = initial_artifacts(model, observations)
    return analyse_identifiability(model, model.jacobian(start, arrays, sig), rcond=rcond)


def _check_options(loss: str, f_scale: float, camera: str) -> None:
    if loss not in LOSSES:
        raise CalibrationError(f"unknown loss {loss!r}; one of {', '.join(LOSSES)}")
    if not (math.isfinite(f_scale) and f_scale > 0):
        raise CalibrationError(f"f_scale must be a positive number of sigmas, got {f_scale!r}")
    if camera not in CAMERA_CHOICES:
        raise CalibrationError(f"camera must be one of {', '.join(CAMERA_CHOICES)}, got {camera!r}")


def identify(
    observations: Sequence[Observation],
    setup: CalibrationSetup,
    *,
    rulers: Sequence[RulerObservation] = (),
    camera: str = "auto",
    sigmas: Sigmas | None = None,
    holdout: Sequence[int] = (),
    rcond: float = 1e-5,
    max_nfev: int = 50,
    loss: str = "linear",
    f_scale: float = 3.0,
    min_separation_mm: float = MIN_SEPARATION_MM,
    clock: Callable[[], dt.datetime] = _utc_now,
) -> CalibrationResult:
    """Identify the arm's kinematic errors, the tool, the artifacts and rulers from a calibration session.

    Parameters
    ----------
    observations
        The session's captures of crossings (see :class:`Observation`).
    setup
        The known and nominal constants (the rulers' taught placements among them).
    rulers
        The session's ruler frames (see :class:`RulerObservation`); their configuration ids share the
        crossings' id space.
    camera
        ``auto`` (default), ``fixed`` or ``fitted``: whether the image scale and the sensor's offset along
        the optical axis are identified (:data:`CAMERA_CHOICES`).
    sigmas
        The measurement's standard deviations that weight the residuals (see :class:`Sigmas`).
    holdout
        Configuration ids left out of the fit for cross-validation (crossings' and rulers').
    rcond
        Subset selection's threshold (see ``analyse_identifiability``).
    max_nfev
        Limit on the optimiser's evaluations.
    loss, f_scale
        The fit's loss (:data:`LOSSES`) and, for a robust one, the residual (in sigmas) beyond which an
        observation weighs less. The covariance is then ``s2 (J^T W J)^-1`` with ``W`` the final weights
        and ``s2`` their weighted variance factor (an M-estimator's approximation).
    min_separation_mm
        Held-out ruler frames closer than this along the ruler are not paired for the absolute error.
    clock
        Gives the result's creation time (UTC).

    Returns
    -------
    CalibrationResult
        Everything the record, the report and ``load_kinematics`` need.

    Raises
    ------
    CalibrationError
        Bad input or too little data (fewer residuals than identified parameters).
    """
    _check_options(loss, f_scale, camera)
    sig = sigmas or Sigmas()
    held = set(holdout)
    train = [o for o in observations if o.configuration not in held]
    test = [o for o in observations if o.configuration in held]
    ruler_train = [o for o in rulers if o.configuration not in held]
    ruler_test = [o for o in rulers if o.configuration in held]
    if not train:
        raise CalibrationError("every observation is held out: leave some configurations in the fit")
    fitted_camera = camera == "fitted" or (camera == "auto" and bool(ruler_train))
    model = CalibrationModel(
        setup,
        placements=sorted({o.placement for o in train}),
        rulers=sorted({o.ruler for o in ruler_train}),
        camera=fitted_camera,
    )
    unfit = sorted({o.placement for o in test} - set(model.placements))
    unfit_rulers = sorted({o.ruler for o in ruler_test} - set(model.rulers))
    if unfit or unfit_rulers:
        what = f"placements {unfit}" if unfit else f"rulers {unfit_rulers}"
        raise CalibrationError(f"held-out {what} have no capture in the fit: hold out fewer configurations")
    arrays = observation_arrays(train, model.placements)
    problem = Problem(model, arrays, sig, ruler_arrays(ruler_train, model.rulers) if ruler_train else None)
    m = problem.residual_count
    if m <= len(model.placement_indices()):
        raise CalibrationError(
            f"{m} residuals cannot even place {len(model.placements)} artifact(s) and {len(model.rulers)}"
            " ruler(s): capture more configurations"
        )
    # (1) the "before": nominal kinematics and camera, placements fitted alone
    start = initial_rulers(model, ruler_train, initial_artifacts(model, train))
    before, _ = least_squares(problem, start, model.placement_indices(), max_nfev)
    # (2) identifiability at nominal
    report = analyse_identifiability(model, problem.jacobian(before), rcond=rcond)
    free = [model.index[n] for n in report.identified]
    log.info(
        "identifying %d parameters from %d observations and %d ruler frames (%d held out); condition number"
        " %.3g; not determined by this data: %s",
        len(free),
        len(arrays),
        len(ruler_train),
        len(test) + len(ruler_test),
        report.condition_number,
        ", ".join(report.deficient) or "none",
    )
    if m <= len(free):
        raise CalibrationError(
            f"{m} residuals cannot determine {len(free)} parameters: capture more configurations"
        )
    # (3) the fit
    delta, sol = least_squares(problem, before, free, max_nfev, loss, f_scale)
    # (4) covariance on the identified subset
    J = problem.jacobian(delta, free)
    r = problem.residuals(delta)
    w = robust_weights(r, loss, f_scale)
    dof = m - len(free)
    s2 = float(np.sum(w * r * r) / dof)
    cov = s2 * np.linalg.pinv(J.T @ (J * w[:, None]), rcond=1e-15, hermitian=True)
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * model.internal_unit[free]
    t95 = float(scipy.stats.t.ppf(0.975, dof))
    params = _estimates(model, delta, dict(zip(free, sigma, strict=True)), t95)
    # (5) cross-validation
    cv = cross_validation(
        model, (before, delta), problem, sorted(held), (test, ruler_test), min_separation_mm
    )
    rulers_summary = None
    if problem.rulers is not None:
        rulers_summary = {
            "before": ruler_residual_summary(model, before, problem.rulers),
            "after": ruler_residual_summary(model, delta, problem.rulers),
        }
    return CalibrationResult(
        software_version=station.__version__,
        created=clock().astimezone(dt.UTC).isoformat(),
        nominal_dh=[DHRowModel.of(row) for row in setup.nominal_dh],
        calibrated_dh=[DHRowModel.of(row) for row in model.dh(delta)],
        nominal_tool=setup.nominal_tool.tolist(),
        calibrated_tool=model.tool(delta).tolist(),
        camera=CameraModelModel.of(model.camera(delta)),
        sensor_mount=model.sensor_mount(delta).tolist(),
        parameters=params,
        identified_count=len(free),
        condition_number=report.condition_number,
        unidentifiable=report.unidentifiable,
        identifiability=_identifiability_model(report),
        residuals={
            "before": residual_summary(model, before, arrays),
            "after": residual_summary(model, delta, arrays),
        },
        cross_validation=cv,
        fit=FitSummary(
            method=method(loss),
            loss=loss,
            f_scale=None if loss == "linear" else f_scale,
            downweighted=int(np.sum(w < 0.5)),
            evaluations=int(sol.nfev),
            status=int(sol.status),
            message=str(sol.message),
            observations=len(arrays) + (0 if problem.rulers is None else len(problem.rulers)),
            residuals=m,
            dof=dof,
            s2=s2,
        ),
        sigmas_mm={"xy": sig.xy_mm, "z": sig.z_mm, **({"ruler": sig.ruler_mm} if problem.rulers else {})},
        magnification=_magnification(model, params) if model.camera_free else None,
        ruler_residuals=rulers_summary,
    )


def _estimates(
    model: CalibrationModel, delta: FloatArray, sigma_of: dict[int, float], t95: float
) -> list[ParameterEstimate]:
    """Every parameter's estimate; ``d2`` reported as ``d2+d3``."""
    params = []
    values = model.nominal + delta
    nominal = model.nominal.copy()
    i_d2, i_d3 = model.index["d2"], model.index["d3"]
    nominal[i_d2] += model.nominal[i_d3]  # d2 is reported as d2+d3
    values[i_d2] += values[i_d3]
    for i, name in enumerate(model.names):
        s = sigma_of.get(i)
        params.append(
            ParameterEstimate(
                name=reported_name(name) if name == "d2" else name,
                unit=model.units[i],
                nominal=float(nominal[i]),
                estimate=float(values[i]),
                sigma=None if s is None else float(s),
                interval=None if s is None else (float(values[i] - t95 * s), float(values[i] + t95 * s)),
                identified=s is not None,
                structural=name in STRUCTURAL,
            )
        )
    return params


def _magnification(model: CalibrationModel, params: list[ParameterEstimate]) -> Magnification:
    by_name = {p.name: p for p in params}
    scale, sensor = by_name["px_per_mm"], by_name["sensor_z"]
    return Magnification(
        px_per_mm=scale.estimate,
        nominal_px_per_mm=scale.nominal,
        sigma=scale.sigma,
        interval=scale.interval,
        relative_to_nominal=scale.estimate / scale.nominal - 1.0,
        sensor_z_mm=sensor.estimate,
    )


def _identifiability_model(report: IdentifiabilityReport) -> IdentifiabilityModel:
    def deficiency(d: Deficiency) -> DeficiencyModel:
        return DeficiencyModel(
            name=reported_name(d.name), combination=d.combination, residual=d.residual, reason=d.reason
        )

    return IdentifiabilityModel(
        rcond=report.rcond,
        singular_values=list(report.singular_values),
        null_dimension=report.null_dimension,
        structural=[deficiency(d) for d in report.structural],
        structural_verified=report.structural_verified,
        deficient=[reported_name(n) for n in report.deficient],
        dropped=[deficiency(d) for d in report.dropped],
    )


__all__ = [
    "CAMERA_CHOICES",
    "LOSSES",
    "analyse",
    "identify",
    "initial_artifacts",
    "residual_summary",
    "robust_weights",
]
