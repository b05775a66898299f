"""How a fit does on what it did not see: residual summaries, and the held-out configurations' relative
error (near the artifacts) and absolute error (along the rulers), before and after."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from station.calibration._absolute import absolute_error_um, absolute_floor_um
from station.calibration._fit import Problem
from station.calibration._metric import relative_error_um
from station.calibration._model import CalibrationModel
from station.calibration._observations import (
    CalibrationError,
    FloatArray,
    Observation,
    ObservationArrays,
    observation_arrays,
)
from station.calibration._result import (
    ABSOLUTE_ERROR_MEANS,
    RELATIVE_ERROR_MEANS,
    CrossValidation,
    ResidualSummary,
    RulerResidualSummary,
)
from station.calibration._ruler_observations import RulerArrays, RulerObservation


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


def ruler_residual_summary(
    model: CalibrationModel, delta: FloatArray, rulers: RulerArrays
) -> RulerResidualSummary:
    """RMS and largest residuals of ruler frames under ``delta``."""
    st, rel, dz = model.ruler_residuals(delta, rulers)
    r = np.linalg.norm(st, axis=1)
    return RulerResidualSummary(
        n=len(rulers),
        rms_st_mm=float(np.sqrt(np.mean(r**2))),
        max_st_mm=float(r.max()),
        n_scale=int(rel.size),
        rms_scale_ppm=float(np.sqrt(np.mean(rel**2)) * 1e6) if rel.size else None,
        n_z=int(dz.size),
        rms_z_mm=float(np.sqrt(np.mean(dz**2))) if dz.size else None,
    )


def cross_validation(
    model: CalibrationModel,
    fits: tuple[FloatArray, FloatArray],
    problem: Problem,
    held: list[int],
    tests: tuple[list[Observation], list[RulerObservation]],
    min_separation_mm: float,
) -> CrossValidation:
    """Held-out residuals, the relative error (crossings) and the absolute error (rulers), before and
    after; the absolute error's floor from the fitted ruler frames' scatter."""
    before, delta = fits
    test, ruler_test = tests
    setup = model.setup
    cv = CrossValidation(
        held_out_configurations=held, n_observations=len(test), n_ruler_observations=len(ruler_test)
    )
    measures: dict[str, str] = {}
    if test:
        test_arrays = observation_arrays(test, model.placements)
        rel: dict[str, float] = {}
        try:
            rel["before"] = relative_error_um(
                test, model.kinematics(before), setup.camera, setup.sensor_mount
            )
            rel["after"] = relative_error_um(
                test, model.kinematics(delta), model.camera(delta), model.sensor_mount(delta)
            )
            measures["relative_error_um"] = RELATIVE_ERROR_MEANS
        except CalibrationError:
            rel = {}
        cv = cv.model_copy(
            update={
                "before": residual_summary(model, before, test_arrays),
                "after": residual_summary(model, delta, test_arrays),
                "relative_error_um": rel,
            }
        )
    if ruler_test and problem.rulers is not None:
        absolute: dict[str, float] = {}
        judged = (
            (before, setup.camera, setup.sensor_mount),
            (delta, model.camera(delta), model.sensor_mount(delta)),
        )
        try:
            for key, (d, cam, mount) in zip(("before", "after"), judged, strict=True):
                _, rotations = model.ruler_frames(d)
                normals = {r: rotations[i, :, 2] for i, r in enumerate(model.rulers)}
                absolute[key] = absolute_error_um(
                    ruler_test,
                    model.kinematics(d),
                    cam,
                    mount,
                    min_separation_mm=min_separation_mm,
                    plane_normals=normals,
                )
            st, _, _ = model.ruler_residuals(delta, problem.rulers)
            absolute["floor"] = absolute_floor_um(float(np.sqrt(np.mean(st**2))))
            measures["absolute_error_um"] = ABSOLUTE_ERROR_MEANS
        except CalibrationError:
            absolute = {}
        cv = cv.model_copy(
            update={"absolute_error_um": absolute, "absolute_pairs": _pairs(ruler_test, min_separation_mm)}
        )
    return cv.model_copy(update={"measures": measures})


def _pairs(frames: Sequence[RulerObservation], min_separation_mm: float) -> int:
    poses = [o for o in frames if o.kind == "pose"]
    return sum(
        1
        for i, a in enumerate(poses)
        for b in poses[i + 1 :]
        if a.ruler == b.ruler
        and a.configuration != b.configuration
        and abs(a.position_mm - b.position_mm) >= min_separation_mm
    )


__all__ = ["cross_validation", "residual_summary", "ruler_residual_summary"]
