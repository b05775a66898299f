"""Identification: the kinematic errors, tool and artifact poses that best explain the captures.

Order of work: (1) the artifacts' positions from the captures under the nominal model (a start, and the
"before" fit: nominal kinematics, artifacts fitted alone); (2) identifiability at nominal
(``analyse_identifiability``): the structural list is verified and left at nominal, subset selection
drops what this data set does not determine; (3) ``scipy.optimize.least_squares`` on the identified
subset (central-difference Jacobian, internal units mm and mrad); (4) covariance ``s^2 (J^T J)^-1``
with ``s^2`` from the residuals, 95 % intervals from Student's t; (5) residuals of the configurations
held out of the fit, and their relative error (``relative_error_um``) before and after.
"""

from __future__ import annotations

import datetime as dt
import logging
import math
from collections.abc import Callable, Sequence

import numpy as np
import scipy.optimize
import scipy.stats

import station
from station.calibration._identifiability import (
    STRUCTURAL,
    Deficiency,
    IdentifiabilityReport,
    analyse_identifiability,
    reported_name,
)
from station.calibration._metric import crossing_positions, relative_error_um
from station.calibration._model import CalibrationModel, Sigmas
from station.calibration._observations import (
    CalibrationError,
    CalibrationSetup,
    FloatArray,
    Observation,
    ObservationArrays,
    observation_arrays,
)
from station.calibration._result import (
    CalibrationResult,
    CameraModelModel,
    CrossValidation,
    DeficiencyModel,
    DHRowModel,
    FitSummary,
    IdentifiabilityModel,
    ParameterEstimate,
    ResidualSummary,
)

log = logging.getLogger(__name__)


def _utc_now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def residual_summary(
    model: CalibrationModel, delta: FloatArray, arrays: ObservationArrays
) -> ResidualSummary:
    """RMS and largest residuals (mm) of ``arrays`` under ``delta``, and each observation's (µm, to
    0.01 µm: an outlier shows in the report's histogram)."""
    xy, dz = model.residuals_mm(delta, arrays)
    r = np.linalg.norm(xy, axis=1)
    return ResidualSummary(
        n=len(arrays),
        rms_xy_mm=float(np.sqrt(np.mean(r**2))),
        max_xy_mm=float(r.max()),
        n_z=int(dz.size),
        rms_z_mm=float(np.sqrt(np.mean(dz**2))) if dz.size else None,
        max_z_mm=float(np.abs(dz).max()) if dz.size else None,
        xy_um=np.round(r * 1000.0, 2).tolist(),
        z_um=np.round(dz * 1000.0, 2).tolist(),
    )


def _least_squares(
    model: CalibrationModel,
    delta0: FloatArray,
    free: Sequence[int],
    arrays: ObservationArrays,
    sigmas: Sigmas,
    max_nfev: int,
    loss: str = "linear",
    f_scale: float = 1.0,
) -> tuple[FloatArray, scipy.optimize.OptimizeResult]:
    idx = np.asarray(free, dtype=int)
    unit = model.internal_unit[idx]

    def full(x: FloatArray) -> FloatArray:
        d = delta0.copy()
        d[idx] = delta0[idx] + x * unit
        return d

    def fun(x: FloatArray) -> FloatArray:
        return model.weighted_residuals(full(x), arrays, sigmas)

    def jac(x: FloatArray) -> FloatArray:
        return model.jacobian(full(x), arrays, sigmas, free)

    sol = scipy.optimize.least_squares(
        fun,
        np.zeros(idx.size),
        jac=jac,
        method=_method(loss),
        loss=loss,
        f_scale=f_scale,
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-10,
        max_nfev=max_nfev,
    )
    return full(sol.x), sol


LOSSES = ("linear", "soft_l1", "huber", "cauchy")
"""The fit's losses (``scipy.optimize.least_squares``'s names): ``linear`` is least squares; the others
weigh a residual beyond ``f_scale`` sigmas less, so that an outlier (a mismeasured capture) pulls less."""


def _method(loss: str) -> str:
    """The optimiser's method for ``loss``: Levenberg-Marquardt, which has no robust loss, or trf."""
    return "lm" if loss == "linear" else "trf"


def robust_weights(r: FloatArray, loss: str, f_scale: float) -> FloatArray:
    """Each (sigma-weighted) residual's weight ``rho'(z)``, ``z = (r / f_scale)^2``, at the solution: the
    iteratively reweighted least-squares view of the robust fit (1 everywhere for ``linear``)."""
    z = (np.asarray(r, dtype=float) / f_scale) ** 2
    if loss == "linear":
        return np.ones_like(z)
    if loss == "soft_l1":
        return np.asarray(1.0 / np.sqrt(1.0 + z))
    if loss == "huber":
        return np.where(z <= 1.0, 1.0, 1.0 / np.sqrt(np.maximum(z, 1.0)))
    if loss == "cauchy":
        return np.asarray(1.0 / (1.0 + z))
    raise CalibrationError(f"unknown loss {loss!r}; one of {', '.join(LOSSES)}")


def initial_artifacts(model: CalibrationModel, observations: Sequence[Observation]) -> FloatArray:
    """Errors with the artifacts' positions from the captures under the nominal model (the mean crossing
    position per placement); the nominal position where a placement has no capture with a reading."""
    delta = model.zeros()
    kin = model.kinematics(delta)
    setup = model.setup
    for i, k in enumerate(model.placements):
        seen = [o for o in observations if o.placement == k and o.z_mm is not None]
        if not seen:
            continue
        p = np.nanmean(crossing_positions(seen, kin, setup.camera, setup.sensor_mount), axis=0)
        delta[model.artifact_delta_indices(i)[:3]] = p - np.asarray(setup.artifacts[k], dtype=float)
    return delta


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
    model = CalibrationModel(setup, placements=sorted({o.placement for o in observations}))
    arrays = observation_arrays(observations, model.placements)
    start = initial_artifacts(model, observations)
    return analyse_identifiability(model, model.jacobian(start, arrays, sig), rcond=rcond)


def identify(
    observations: Sequence[Observation],
    setup: CalibrationSetup,
    *,
    sigmas: Sigmas | None = None,
    holdout: Sequence[int] = (),
    rcond: float = 1e-5,
    max_nfev: int = 50,
    loss: str = "linear",
    f_scale: float = 3.0,
    clock: Callable[[], dt.datetime] = _utc_now,
) -> CalibrationResult:
    """Identify the arm's kinematic errors, the tool and the artifacts from a calibration session.

    Parameters
    ----------
    observations
        The session's captures (see :class:`Observation`).
    setup
        The known and nominal constants.
    sigmas
        The measurement's standard deviations that weight the residuals (5 um each by default).
    holdout
        Configuration ids left out of the fit for cross-validation.
    rcond
        Subset selection's threshold (see ``analyse_identifiability``).
    max_nfev
        Limit on the optimiser's evaluations.
    loss, f_scale
        The fit's loss (:data:`LOSSES`) and, for a robust one, the residual (in sigmas) beyond which an
        observation weighs less. The covariance is then ``s2 (J^T W J)^-1`` with ``W`` the final weights
        and ``s2`` their weighted variance factor (an M-estimator's approximation).
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
    if loss not in LOSSES:
        raise CalibrationError(f"unknown loss {loss!r}; one of {', '.join(LOSSES)}")
    if not (math.isfinite(f_scale) and f_scale > 0):
        raise CalibrationError(f"f_scale must be a positive number of sigmas, got {f_scale!r}")
    sig = sigmas or Sigmas()
    held = set(holdout)
    train = [o for o in observations if o.configuration not in held]
    test = [o for o in observations if o.configuration in held]
    if not train:
        raise CalibrationError("every observation is held out: leave some configurations in the fit")
    model = CalibrationModel(setup, placements=sorted({o.placement for o in train}))
    unfit = sorted({o.placement for o in test} - set(model.placements))
    if unfit:
        raise CalibrationError(
            f"held-out placements {unfit} have no capture in the fit: hold out fewer configurations"
        )
    arrays = observation_arrays(train, model.placements)

    m = 2 * len(arrays) + int(arrays.has_z.sum())
    if m <= len(model.artifact_indices()):
        raise CalibrationError(
            f"{m} residuals cannot even place {len(model.placements)} artifact(s):"
            " capture more configurations"
        )
    # (1) the "before": nominal kinematics, artifacts fitted alone
    start = initial_artifacts(model, train)
    before, _ = _least_squares(model, start, model.artifact_indices(), arrays, sig, max_nfev)
    # (2) identifiability at nominal
    report = analyse_identifiability(model, model.jacobian(before, arrays, sig), rcond=rcond)
    free = [model.index[n] for n in report.identified]
    log.info(
        "identifying %d parameters from %d observations (%d held out); condition number %.3g;"
        " not determined by this data: %s",
        len(free),
        len(arrays),
        len(test),
        report.condition_number,
        ", ".join(report.deficient) or "none",
    )
    if m <= len(free):
        raise CalibrationError(
            f"{m} residuals cannot determine {len(free)} parameters: capture more configurations"
        )
    # (3) the fit
    delta, sol = _least_squares(model, before, free, arrays, sig, max_nfev, loss, f_scale)
    # (4) covariance on the identified subset
    J = model.jacobian(delta, arrays, sig, free)
    r = model.weighted_residuals(delta, arrays, sig)
    w = robust_weights(r, loss, f_scale)
    dof = m - len(free)
    s2 = float(np.sum(w * r * r) / dof)
    cov = s2 * np.linalg.pinv(J.T @ (J * w[:, None]), rcond=1e-15, hermitian=True)
    sigma = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * model.internal_unit[free]
    t95 = float(scipy.stats.t.ppf(0.975, dof))
    sigma_of = dict(zip(free, sigma, strict=True))
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
    # (5) cross-validation
    cv = CrossValidation(held_out_configurations=sorted(held), n_observations=len(test))
    if test:
        test_arrays = observation_arrays(test, model.placements)
        rel: dict[str, float] = {}
        try:
            rel["before"] = relative_error_um(
                test, model.kinematics(before), setup.camera, setup.sensor_mount
            )
            rel["after"] = relative_error_um(test, model.kinematics(delta), setup.camera, setup.sensor_mount)
        except CalibrationError:
            rel = {}
        cv = CrossValidation(
            held_out_configurations=sorted(held),
            n_observations=len(test),
            before=residual_summary(model, before, test_arrays),
            after=residual_summary(model, delta, test_arrays),
            relative_error_um=rel,
        )
    return CalibrationResult(
        software_version=station.__version__,
        created=clock().astimezone(dt.UTC).isoformat(),
        nominal_dh=[DHRowModel.of(row) for row in setup.nominal_dh],
        calibrated_dh=[DHRowModel.of(row) for row in model.dh(delta)],
        nominal_tool=setup.nominal_tool.tolist(),
        calibrated_tool=model.tool(delta).tolist(),
        camera=CameraModelModel.of(setup.camera),
        sensor_mount=setup.sensor_mount.tolist(),
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
            method=_method(loss),
            loss=loss,
            f_scale=None if loss == "linear" else f_scale,
            downweighted=int(np.sum(w < 0.5)),
            evaluations=int(sol.nfev),
            status=int(sol.status),
            message=str(sol.message),
            observations=len(arrays),
            residuals=m,
            dof=dof,
            s2=s2,
        ),
        sigmas_mm={"xy": sig.xy_mm, "z": sig.z_mm},
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


__all__ = ["analyse", "identify", "initial_artifacts", "residual_summary"]
