"""A simulated calibration session judged against the sim world's truth (tests and benchmarks only).

The station never sees the true arm; here it is compared with what the station identified:

* ``floor_um``: the relative error of the held-out configurations with the **true** model (the true DH
  table and camera transform): what the arm's repeatability and the measurement's noise leave, the
  calibration's floor;
* per identified parameter, the truth (the true arm expressed in the identified parameters by
  ``station.calibration.equivalent_errors``: the structural ones held at nominal), the error in sigmas
  and whether the 95 % interval holds it.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from sim.world import World, WorldSpec
from station.calibration import CalibrationModel, CalibrationResult, relative_error_um, true_values
from station.config import StationDevices
from station.kinds.calibration.analysis import calibration_setup, observations_from
from station.kinds.calibration.params import CalibrationCell
from station.kinds.calibration.plan import LOOK_DOWN
from station.kinematics import rot_x, rot_y, rot_z, transform
from station.plans import CaptureResult
from station.vision import MeasureParams

FloatArray = npt.NDArray[np.float64]


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
    artifacts = {
        k: (T[:3, 3], T[:3, 2]) for k, T in enumerate(world.artifact_poses()) if k in setup.artifacts
    }
    truth = true_values(model, world.true_dh, world.kinematics.tool, artifacts)
    rows: list[dict[str, Any]] = []
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
        "max_abs_z": float(max(abs(float(r["z"])) for r in rows)) if rows else float("nan"),
        "parameters": rows,
    }


def _estimated_artifact(result: CalibrationResult, setup: Any, k: int) -> tuple[FloatArray, FloatArray]:
    """Artifact ``k``'s crossing and upward normal as the calibration estimated them (its frame)."""
    value = {p.name: p.estimate for p in result.parameters}
    point = np.array([value[f"artifact{k}_x"], value[f"artifact{k}_y"], value[f"artifact{k}_z"]])
    n0 = np.asarray(setup.normal(k), dtype=float)
    rx, ry = math.radians(value[f"artifact{k}_rx"]), math.radians(value[f"artifact{k}_ry"])
    return point, rot_x(rx) @ rot_y(ry) @ n0


def pointing_errors_um(
    devices: StationDevices,
    cell: CalibrationCell,
    result: CalibrationResult,
    *,
    placements: Sequence[int],
    turn_deg: float = 25.0,
    calibrated: bool = True,
    measure_params: MeasureParams | None = None,
    settle_s: float = 0.25,
) -> list[float | None]:
    """Where the crossing lands, relative to the optical axis (um in the artifact plane), when the arm is
    sent to look square at each placement's crossing from a turn not in the session: with the calibrated
    model to the estimated artifact (a compensated move), or with the nominal model to the taught one.

    The arm travels through lift poses between placements (as the plan does), every waypoint checked.
    ``devices`` must be connected (robot, camera). None where the crossing is not measured (out of view
    or focus). The arm settles ``settle_s`` (wall time) before each capture.
    """
    from station.camera_moves import move_camera
    from station.kinds.calibration.plan import square_on
    from station.vision import MeasurementError, measure

    robot = devices.robot
    assert robot is not None
    kin = result.kinematics() if calibrated else cell.kinematics
    setup = calibration_setup(cell, 640, 480)
    cx, cy = setup.camera.principal_px
    out: list[float | None] = []
    for k in placements:
        if calibrated:
            point, up = _estimated_artifact(result, setup, k)
        else:
            point = np.asarray(cell.artifacts_mm[k], dtype=float)
            up = np.asarray(setup.normal(k), dtype=float)
        up = up / np.linalg.norm(up)
        turn = (cell.artifact_turns_deg[k] if cell.artifact_turns_deg else 0.0) + turn_deg
        pose = transform(
            square_on(up) @ LOOK_DOWN @ rot_z(math.radians(turn)), point + cell.working_distance_mm * up
        )
        move_camera(robot, kin, pose, max_step_deg=cell.max_step_deg * 0.9, through_lift=True)
        time.sleep(settle_s)
        frame = devices.camera.grab()
        try:
            m = measure(frame.image, measure_params or MeasureParams())
        except MeasurementError:  # the crossing is out of view or out of focus
            out.append(None)
            continue
        depth = cell.working_distance_mm
        dx = (m.center_px[0] - cx) * depth / cell.focal_px
        dy = (m.center_px[1] - cy) * depth / cell.focal_px
        out.append(math.hypot(dx, dy) * 1000.0)
    return out


__all__ = ["pointing_errors_um", "truth_report"]
