"""The rulers fixed in the simulated cell (issue 22): where they lie, and what a camera pose sees of them.

Each ruler (``station/vision/RULER.md``: 250 mm graduated, chrome on glass) lies on a glass substrate
:data:`SUBSTRATE_WIDTH_MM` wide reaching :data:`SUBSTRATE_END_MM` beyond its end graduations, on the
table's plane or on an angle block. Its frame: origin at graduation 0 on the axis (``t = 0``) on the
top surface, ``s`` along it, ``t`` across it and ``n = s x t`` into the substrate (away from a camera
that reads it), as ``sim.ruler`` and ``station.calibration.RulerPlacement`` have it.

:data:`DEFAULT_RULERS`, away from the arm's other artifacts, on the side of the cell opposite the X-Y
table: two on the table's plane (one along the base's +y, one along +x) and one on an angle block
turned 25 deg about its length, 40 mm above the plane; a camera square on any of them, 68 mm from it,
is reached at every 90 deg turn about its axis along their whole length (two to four joint solutions).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from sim._render_camera import Pose
from station.kinematics import rot_x, rot_z, transform

FloatArray = npt.NDArray[np.float64]

SUBSTRATE_WIDTH_MM = 30.0
"""Width of each ruler's glass (the pattern, 3.2 mm across, runs along its middle)."""
SUBSTRATE_END_MM = 10.0
"""How far the glass reaches beyond graduation 0 and the last graduation."""
RULER_LENGTH_MM = 250.0
"""The graduated length (``RulerSpec().length_mm``)."""

#: Level, ``s`` along the base's x, ``n`` down: ``t`` along the base's -y (``n = s x t``).
_FLAT = np.diag([1.0, -1.0, -1.0])


@dataclass(frozen=True)
class RulerMount:
    """A ruler fixed in the cell, as mounted (base frame).

    Attributes
    ----------
    x_mm, y_mm
        Graduation 0's point on the axis, horizontally (mm).
    height_mm
        Its top surface above the table's plane (mm): 0 on the table, a block's height otherwise.
    yaw_deg
        The direction of +s, turned about the base's +z from its +x (deg).
    tilt_deg
        The surface turned about the ruler's own +s (an angle block; 0: level), deg.
    name
        What the cell calls it.
    """

    x_mm: float
    y_mm: float
    height_mm: float = 0.0
    yaw_deg: float = 0.0
    tilt_deg: float = 0.0
    name: str = "ruler"

    def __post_init__(self) -> None:
        values = (self.x_mm, self.y_mm, self.height_mm, self.yaw_deg, self.tilt_deg)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"a ruler mount's coordinates must be finite, got {values}")
        if abs(self.tilt_deg) >= 45.0:
            raise ValueError(f"an angle block's tilt must be within 45 deg, got {self.tilt_deg}")

    def frame(self, table_z_mm: float) -> FloatArray:
        """The ruler's 4x4 frame in the base frame, its table plane at height ``table_z_mm``."""
        R = rot_z(math.radians(self.yaw_deg)) @ _FLAT @ rot_x(math.radians(self.tilt_deg))
        return transform(R, (self.x_mm, self.y_mm, table_z_mm + self.height_mm))


DEFAULT_RULERS: tuple[RulerMount, ...] = (
    RulerMount(-500.0, -150.0, 0.0, 90.0, 0.0, "table, along +y"),
    RulerMount(-500.0, -250.0, 0.0, 0.0, 0.0, "table, along +x"),
    RulerMount(-550.0, 100.0, 40.0, 90.0, 25.0, "angle block, along +y, 25 deg"),
)
"""The simulated cell's rulers (see the module notes)."""


def on_substrate(s_mm: float, t_mm: float) -> bool:
    """Whether the ruler point ``(s, t)`` (mm) lies on its glass."""
    half = SUBSTRATE_WIDTH_MM / 2.0
    return -SUBSTRATE_END_MM <= s_mm <= RULER_LENGTH_MM + SUBSTRATE_END_MM and abs(t_mm) <= half


def ray_hit(
    origin: FloatArray, direction: FloatArray, ruler_frame: FloatArray
) -> tuple[float, float, float] | None:
    """Where a ray meets a ruler's top surface: ``(s, t, distance along the ray)``, or None when it runs
    parallel to it, meets it behind its origin or from beneath (the surface faces away)."""
    n = ruler_frame[:3, 2]
    along = float(n @ direction)
    if along <= 1e-9:  # n points into the substrate: a ray reading the top runs along +n
        return None
    distance = float(n @ (ruler_frame[:3, 3] - origin)) / along
    if distance <= 0:
        return None
    local = ruler_frame[:3, :3].T @ (origin + distance * direction - ruler_frame[:3, 3])
    return float(local[0]), float(local[1]), distance


def seen_ruler(camera_pose: FloatArray, frames: list[FloatArray]) -> int | None:
    """Index of the ruler whose glass the camera's optical axis meets (the nearest), or None."""
    best: tuple[float, int] | None = None
    for i, F in enumerate(frames):
        hit = ray_hit(camera_pose[:3, 3], camera_pose[:3, 2], F)
        if hit is not None and on_substrate(hit[0], hit[1]) and (best is None or hit[2] < best[0]):
            best = (hit[2], i)
    return None if best is None else best[1]


def ruler_view(ruler_in_camera: FloatArray, working_distance_mm: float) -> tuple[Pose, float]:
    """``sim.ruler``'s pose and anchor for a ruler frame given in the camera frame (4x4).

    The anchor is the ruler position where the optical axis meets the ruler's surface (or graduation 0
    when it does not), so that the pose's origin lies in view.
    """
    T = ruler_in_camera
    hit = ray_hit(np.zeros(3), np.array([0.0, 0.0, 1.0]), T)
    anchor = hit[0] if hit is not None else 0.0
    R = T[:3, :3]
    origin = T[:3, 3] + R[:, 0] * anchor
    b = math.asin(max(-1.0, min(1.0, float(R[0, 2]))))
    a = math.atan2(-float(R[1, 2]), float(R[2, 2]))
    c = math.atan2(-float(R[0, 1]), float(R[0, 0]))
    pose = Pose(
        float(origin[0]),
        float(origin[1]),
        rotation_deg=math.degrees(c),
        tilt_x_deg=math.degrees(a),
        tilt_y_deg=math.degrees(b),
        z_mm=float(origin[2]) - working_distance_mm,
    )
    return pose, anchor


__all__ = [
    "DEFAULT_RULERS",
    "RULER_LENGTH_MM",
    "SUBSTRATE_END_MM",
    "SUBSTRATE_WIDTH_MM",
    "RulerMount",
    "on_substrate",
    "ray_hit",
    "ruler_view",
    "seen_ruler",
]
