"""The camera-calibration target on the simulated X-Y table (``WorldSpec.calibration_target``).

The standard target (``station.camcal.STANDARD_TARGET``) lies on the table's carriage in place of the
crossed-groove artifact, in the artifact's frame (its x along the artifact's u, its y along v, its z into
the table), centred where the crossing was: at the reference pose and table (0, 0) the camera is square
to its centre, in focus. Its frames are rendered by ``sim.target.render_target`` through the camera's true
intrinsics (``World.true_intrinsics``: ``sim.lens.true_intrinsics`` of ``WorldSpec.true_intrinsics_seed``),
with the world's noise preset and defocus; the distance sensor reads the table's plane, which the target
lies in.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt

from sim.presets import get_preset
from sim.target import TargetPose, TargetTruth, render_target
from station.camcal import STANDARD_TARGET
from station.camera_model import CameraIntrinsics

__all__ = ["render_table_target", "target_frame"]

FloatArray = npt.NDArray[np.float64]


def target_frame(artifact_pose: FloatArray) -> FloatArray:
    """The target's 4x4 frame in the base frame, for the table artifact's frame (its crossing)."""
    w, h = STANDARD_TARGET.size_mm
    corner = np.eye(4)
    corner[:3, 3] = (-w / 2.0, -h / 2.0, 0.0)
    return np.asarray(artifact_pose @ corner, dtype=np.float64)


def render_table_target(
    camera_pose: FloatArray,
    artifact_pose: FloatArray,
    spec: Any,
    intrinsics: CameraIntrinsics,
    rng: np.random.Generator,
    exposure: float = 1.0,
) -> tuple[npt.NDArray[np.uint8], TargetTruth] | None:
    """The frame a camera at ``camera_pose`` (4x4, base frame) takes of the target on the table whose
    artifact frame is ``artifact_pose``, through ``intrinsics``, with the world's (``spec``: its
    ``WorldSpec``) noise preset, focus and defocus; with its truth. None where the target's plane does not
    fill the view (the camera facing away, or a horizon in view: the caller shows the background)."""
    T = np.asarray(np.linalg.solve(camera_pose, target_frame(artifact_pose)), dtype=np.float64)
    if T[2, 3] <= 1.0 or T[2, 2] <= 0.0:
        return None
    preset = get_preset(spec.preset)
    lit = replace(
        preset,
        land_level_dn=min(preset.land_level_dn * exposure, 255.0),
        paint_level_dn=min(preset.paint_level_dn * exposure, 254.0),
    )
    try:
        return render_target(
            TargetPose(T[:3, :3], T[:3, 3]),
            intrinsics=intrinsics,
            target=STANDARD_TARGET,
            preset=lit,
            focus_mm=float(spec.camera.working_distance_mm),
            defocus_px_per_mm=float(spec.defocus_px_per_mm),
            rng=rng,
        )
    except ValueError:
        return None
