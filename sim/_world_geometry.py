"""Small geometry of the simulated world: a crossing's position from a homography, Euler angles, and
which artifact-plane points a frame's pixels see."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


def center_mm_of(
    homography: FloatArray, relative_to_px: tuple[float, float] = (0.0, 0.0)
) -> tuple[float, float]:
    """The crossing relative to the artifact point seen at pixel ``relative_to_px``, in artifact axes (mm).

    From the artifact mm -> image px homography: minus that pixel's back-projection onto the artifact
    plane. At the image origin (the default) it is ``center_mm`` as ``station.vision.measure`` defines it;
    at the principal point, the tool point the repeatability plan measures.
    """
    px = np.array([relative_to_px[0], relative_to_px[1], 1.0])
    point = np.linalg.solve(np.asarray(homography, dtype=float), px)
    return -float(point[0] / point[2]), -float(point[1] / point[2])


def euler_xyz(R: FloatArray) -> tuple[float, float, float]:
    """Angles (deg) a, b, c with ``R = rot_x(a) @ rot_y(b) @ rot_z(c)`` (sim.artifact.Pose's order)."""
    b = math.asin(max(-1.0, min(1.0, float(R[0, 2]))))
    a = math.atan2(-float(R[1, 2]), float(R[2, 2]))
    c = math.atan2(-float(R[0, 1]), float(R[0, 0]))
    return math.degrees(a), math.degrees(b), math.degrees(c)


def on_artifact(H_inv: FloatArray, px: FloatArray) -> FloatArray:
    """Artifact-plane points (mm, N x 2) seen at pixels ``px`` (N x 2) through an image -> artifact
    homography; a pixel whose ray misses the plane (behind the camera) maps to infinity."""
    h = np.column_stack([px, np.ones(len(px))]) @ H_inv.T
    w = h[:, 2:3]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.where(w > 0, h[:, :2] / np.where(w > 0, w, 1.0), np.inf)
    return np.asarray(uv, dtype=np.float64)


__all__ = ["center_mm_of", "euler_xyz", "on_artifact"]
