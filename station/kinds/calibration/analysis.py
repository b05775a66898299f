"""The ``calibration`` kind's analysis: from a session's captures to the identified arm.

Used by the ``calibration`` plan's analysis (when the session ends) and by ``station calibrate SESSION``
(again, on any stored calibration session: capture and optimisation are separate, the raw images and
their measurements stay in the record). The pure identification is :mod:`station.calibration`; this
module turns the record's captures and the station's configuration into its inputs and its result into
the session's results object:

``relative_error_um``: ``{"before", "after", "floor"}`` over held-out configurations (the mean in-plane
distance between two configurations' measured crossings of one placement, with the nominal and the
calibrated model); ``floor`` is estimated from the ``return`` captures (each configuration's pose
captured again after the in-view motions: the arm's repeatability and the measurement's noise, what no
model removes): ``sqrt(pi)/2`` times the RMS in-plane distance between a configuration's two captures
(for independent isotropic errors of sigma per axis, a pair of configurations is sigma sqrt(pi) apart on
average and a capture and its return 2 sigma RMS). ``condition_number``, ``unidentifiable`` and
``parameters`` (name, nominal, estimate, interval) are the identification's; ``calibration`` is the
whole versioned :class:`~station.calibration.CalibrationResult` (``Kinematics.from_calibration`` loads
it once saved with ``station calibrate SESSION --out FILE``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from station.calibration import (
    CalibrationError,
    CalibrationSetup,
    CameraModel,
    Observation,
    crossing_positions,
    identify,
)
from station.kinds.calibration.meanings import measures_of
from station.kinds.calibration.ruler_analysis import (
    ruler_holdout,
    ruler_observations_from,
    ruler_placements,
    ruler_results,
)
from station.kinematics import Kinematics
from station.plans import CaptureResult, PlanError
from station.plans._ruler import is_ruler

if TYPE_CHECKING:
    from station.kinds.calibration.params import CalibrationCell, CalibrationParams

#: Capture kinds of a calibration session the identification uses ("align" frames are not).
FIT_KINDS = {"pose": "pose", "inview": "inview", "return": "inview"}


def calibration_setup(
    cell: CalibrationCell, width: int, height: int, *, rulers: bool = False
) -> CalibrationSetup:
    """The identification's constants from the cell and the images' size (``rulers``: with the cell's
    rulers' taught placements, for a session that has ruler frames)."""
    if cell.sensor_mount is None:
        raise PlanError("a calibration needs the distance sensor's mount ([distance_sensor] mount)")
    principal = cell.principal_px or ((width - 1) / 2.0, (height - 1) / 2.0)
    return CalibrationSetup(
        camera=CameraModel(
            focal_px=cell.focal_px,
            principal_px=principal,
            width=width,
            height=height,
            working_distance_mm=cell.working_distance_mm,
        ),
        sensor_mount=cell.sensor_mount,
        nominal_tool=cell.kinematics.tool,
        artifacts=dict(enumerate(cell.artifacts_mm)),
        artifact_normals=dict(enumerate(cell.artifact_normals)) if cell.artifact_normals else {},
        rulers=ruler_placements(cell) if rulers else {},
    )


def observations_from(
    captures: Sequence[CaptureResult],
) -> tuple[list[Observation], list[str], list[dict[str, Any]]]:
    """The session's usable captures as observations, each one's capture kind (pose, inview, return),
    and why each other capture is left out."""
    out: list[Observation] = []
    kinds: list[str] = []
    left: list[dict[str, Any]] = []
    for c in captures:
        kind = FIT_KINDS.get(str(c.meta.get("kind")))
        if kind is None or is_ruler(c.meta):  # the rulers' frames: ruler_analysis
            continue
        m = c.measurement
        why = None
        if m is None or not m.get("ok"):
            why = (m or {}).get("error") or "not measured"
        elif c.z_mm is None:
            why = f"no distance reading ({c.meta.get('z_error', 'no sensor')})"
        elif "joints_deg" not in c.meta:
            why = "no joint reading"
        if why is not None:
            left.append({"capture_id": c.capture_id, "kind": c.meta.get("kind"), "reason": why})
            continue
        assert m is not None
        assert c.z_mm is not None
        out.append(
            Observation(
                joints_deg=tuple(c.meta["joints_deg"]),
                center_px=(float(m["center_px"][0]), float(m["center_px"][1])),
                z_mm=float(c.z_mm),
                configuration=int(c.meta["configuration"]),
                placement=int(c.meta["placement"]),
                kind=kind,  # type: ignore[arg-type]
            )
        )
        kinds.append(str(c.meta["kind"]))
    return out, kinds, left


def holdout_configurations(observations: Sequence[Observation], fraction: float, seed: int) -> list[int]:
    """Configurations held out of the fit: ``fraction`` of each placement's (at least two where it has four
    or more, so that each placement gives held-out pairs), drawn with ``seed``."""
    if fraction <= 0:
        return []
    rng = np.random.default_rng([0xCA1, seed])
    held: list[int] = []
    by_placement: dict[int, set[int]] = {}
    for o in observations:
        if o.kind == "pose":
            by_placement.setdefault(o.placement, set()).add(o.configuration)
    for p in sorted(by_placement):
        configs = sorted(by_placement[p])
        n = round(fraction * len(configs))
        if len(configs) >= 4:
            n = max(n, 2)
        n = min(n, len(configs) - 2)  # keep two in the fit
        if n > 0:
            held += [int(c) for c in rng.choice(configs, size=n, replace=False)]
    return sorted(held)


def floor_estimate_um(
    observations: Sequence[Observation], kinds: Sequence[str], kinematics: Kinematics, setup: CalibrationSetup
) -> float | None:
    """The relative error's floor estimated from each configuration's pose and return captures (see the
    module notes); None without such pairs."""
    poses: dict[int, Observation] = {}
    returns: dict[int, Observation] = {}
    for o, kind in zip(observations, kinds, strict=True):
        if kind == "pose":
            poses[o.configuration] = o
        elif kind == "return":
            returns[o.configuration] = o
    both = sorted(set(poses) & set(returns))
    if not both:
        return None
    a = crossing_positions([poses[c] for c in both], kinematics, setup.camera, setup.sensor_mount)
    b = crossing_positions([returns[c] for c in both], kinematics, setup.camera, setup.sensor_mount)
    n = np.array([setup.normal(poses[c].placement) for c in both])  # each artifact's own plane
    d = b - a
    d -= np.sum(d * n, axis=1, keepdims=True) * n
    rms = float(np.sqrt(np.mean(np.sum(d * d, axis=1))))
    return math.sqrt(math.pi) / 2.0 * rms * 1000.0


def analyse_calibration(
    params: CalibrationParams, cell: CalibrationCell, captures: Sequence[CaptureResult], *, planned: int
) -> dict[str, Any]:
    """The calibration session's results object (see the module notes); ``planned``: the configurations
    the session's plan visits."""

    observations, kinds, left_out = observations_from(captures)
    if not observations:
        raise PlanError(
            "no capture of this session can be used (each needs a measured crossing, a distance reading and "
            f"the joints); {len(left_out)} left out, e.g. {left_out[:3]}"
        )
    sizes = {(c.width, c.height) for c in captures if c.width and c.height}
    width, height = max(sizes) if sizes else (640, 480)
    principal = cell.principal_px or ((width - 1) / 2.0, (height - 1) / 2.0)
    frames, ruler_left = ruler_observations_from(captures, cell, principal)
    setup = calibration_setup(cell, width, height, rulers=bool(frames))
    held = holdout_configurations(observations, params.holdout_fraction, params.seed)
    held += ruler_holdout(frames, params.holdout_fraction, params.seed)
    try:
        result = identify(
            observations, setup, rulers=frames, holdout=held, loss=params.loss, f_scale=params.f_scale
        )
    except CalibrationError as exc:
        raise PlanError(f"the identification failed: {exc}") from exc
    cv = result.cross_validation
    rel = cv.relative_error_um
    out = {
        "relative_error_um": {
            "before": rel.get("before"),
            "after": rel.get("after"),
            "floor": floor_estimate_um(observations, kinds, result.kinematics(), setup),
        },
        "floor_source": "estimated from each configuration's return capture (the arm's repeatability)",
        "condition_number": result.condition_number,
        "unidentifiable": list(result.unidentifiable),
        "identified_count": result.identified_count,
        "parameters": [
            {
                "name": p.name,
                "unit": p.unit,
                "nominal": p.nominal,
                "estimate": p.estimate,
                "interval": p.interval,
                "sigma": p.sigma,
                "identified": p.identified,
                "structural": p.structural,
            }
            for p in result.parameters
        ],
        "observations": len(observations),
        "configurations": len({o.configuration for o in observations} | {f.configuration for f in frames}),
        "placements": sorted({o.placement for o in observations}),
        "held_out_configurations": held,
        "planned_configurations": planned,
        "left_out": (left_out + ruler_left)[:50],
        "calibration": result.model_dump(mode="json"),
    }
    if frames:  # a cell without rulers: today's results, key for key
        figures, check = ruler_results(result, frames, captures)
        out.update(figures)
        out["magnification_check"] = check
    out["measures"] = measures_of(out)
    return out


__all__ = [
    "analyse_calibration",
    "calibration_setup",
    "floor_estimate_um",
    "holdout_configurations",
    "observations_from",
]
