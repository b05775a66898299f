"""How wrong a kinematic model is over the whole workspace, against the true arm (benchmarks and tests).

The held-out errors a calibration reports judge it where it measured: near its artifacts
(``relative_error_um``) and along its rulers (``absolute_error_um``). This judges it everywhere the arm
reaches: ``count`` joint vectors drawn uniformly within the joint limits (5 deg inside them) whose
camera stays above the base's plane; for each, the camera point (where the optical axis meets the
capture plane: the pinhole plus the plane's depth along the axis) under the model and under the truth;
the error is the mean, over every pair of poses, of the magnitude of the difference between the two
models' distances between the pair's points (a rigid motion of the whole model costs nothing: only
its shape counts, as for a station that works relative to its artifacts). Truth for benchmarks only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from station.kinematics import Kinematics

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CameraPointModel:
    """A kinematic model (camera as the tool) and the depth of its capture plane along the optical axis."""

    kinematics: Kinematics
    depth_mm: float

    def points(self, joints_deg: FloatArray) -> FloatArray:
        """The camera points (N, 3) at the joints (N, 6)."""
        poses = self.kinematics.tool_pose(joints_deg)
        return np.asarray(poses[:, :3, 3] + self.depth_mm * poses[:, :3, 2], dtype=float)


def workspace_poses(count: int = 400, *, seed: int = 0, margin_deg: float = 5.0) -> FloatArray:
    """``count`` joint vectors (deg) uniform within the A465's limits (``margin_deg`` inside), each with
    the flange above the base's plane."""
    kin = Kinematics()
    lo = kin.joint_limits_deg[:, 0] + margin_deg
    hi = kin.joint_limits_deg[:, 1] - margin_deg
    rng = np.random.default_rng([0x3D, seed])
    out: list[FloatArray] = []
    while len(out) < count:
        q = rng.uniform(lo, hi, (count, 6))
        above = kin.tool_pose(q)[:, 2, 3] > 0.0
        out += list(q[above])
    return np.array(out[:count])


def workspace_distance_error_mm(
    model: CameraPointModel, truth: CameraPointModel, joints_deg: FloatArray
) -> float:
    """Mean magnitude (mm) of the model's distance between two poses' camera points minus the truth's,
    over every pair of ``joints_deg`` (see the module notes)."""
    a, b = model.points(joints_deg), truth.points(joints_deg)
    i, j = np.triu_indices(len(joints_deg), k=1)
    da = np.linalg.norm(a[i] - a[j], axis=1)
    db = np.linalg.norm(b[i] - b[j], axis=1)
    return float(np.mean(np.abs(da - db)))


__all__ = ["CameraPointModel", "workspace_distance_error_mm", "workspace_poses"]
