"""A simulated calibration session judged against the sim world's truth (tests and benchmarks only).

The station never sees the true arm; here it is compared with what the station identified:

* ``floor_um``: the relative error of the held-out configurations with the **true** model (the true DH
  table and camera transform): what the arm's repeatability and the measurement's noise leave, the
  issue's floor;
* per identified parameter, the truth (the true arm expressed in the identified parameters by
  ``station.calibration.equivalent_errors``: the structural ones held at nominal), the error in sigmas
  and whether the 95 % interval holds it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from sim.world import World, WorldSpec
from station.calibration import CalibrationModel, CalibrationResult, equivalent_errors, relative_error_um
from station.calibration import reported_name as calibration_name
from station.calibration_session import calibration_setup, observations_from
from station.plans import CaptureResult
from station.plans.calibration import CalibrationCell


def truth_report(
    results: Mapping[str, Any],
    captures: Sequence[CaptureResult],
    cell: CalibrationCell,
    spec: WorldSpec | None = None,
) -> dict[str, Any]:
    """The session's identification against the truth of the world it ran in (``spec``: its WorldSpec)."""
    world = World(spec or WorldSpec())
    observations, _, _ = observations_from(captures)
    sizes = {(c.width, c.height) for c in captures if c.width and c.height}
    width, height = max(sizes) if sizes else (640, 480)
    setup = calibration_setup(cell, width, height)
    result = CalibrationResult.model_validate(results["calibration"])
    held = set(results["held_out_configurations"])
    held_obs = [o for o in observations if o.configuration in held]
    floor = relative_error_um(held_obs, world.kinematics, setup.camera, setup.sensor_mount)

    model = CalibrationModel(setup)
    artifacts = {k: (T[:3, 3], T[:3, 2]) for k, T in enumerate(world.artifact_poses()) if k in setup.artifacts}
    delta = equivalent_errors(model, world.true_dh, world.kinematics.tool, artifacts)
    values = model.nominal + delta
    values[model.index["d2"]] += model.nominal[model.index["d3"]]
    truth = {
        calibration_name(n) if n == "d2" else n: float(v) for n, v in zip(model.names, values, strict=True)
    }
    rows = []
    for p in result.parameters:
        if not p.identified or not p.sigma or p.name not in truth:
            continue
        z = (p.estimate - truth[p.name]) / p.sigma
        lo, hi = p.interval if p.interval is not None else (np.nan, np.nan)
        rows.append(
            {
                "name": p.name,
                "truth": truth[p.name],
                "estimate": p.estimate,
                "sigma": p.sigma,
                "z": float(z),
                "inside_95": bool(lo <= truth[p.name] <= hi),
            }
        )
    rel = results["relative_error_um"]
    return {
        "before_um": rel["before"],
        "after_um": rel["after"],
        "floor_estimate_um": rel["floor"],
        "floor_um": float(floor),
        "identified": len(rows),
        "inside_95": float(np.mean([r["inside_95"] for r in rows])) if rows else float("nan"),
        "max_abs_z": float(max(abs(r["z"]) for r in rows)) if rows else float("nan"),
        "parameters": rows,
    }


__all__ = ["truth_report"]
