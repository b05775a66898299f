"""Where the camera looks at the target from: the views a camera calibration takes.

A view is a motion of the camera from the *square pose*: the camera square to the target, the target's
centre on the optical axis at the working distance (in focus), the image's x along the target's x. From
there, in this order: a shift across (``shift_mm``, in the square pose's x and y), a tilt by
``tilt_deg`` about an axis through the in-focus point (so that the middle of the image stays in focus),
the axis at ``azimuth_deg`` from the square pose's x, in its xy plane; a turn about the (tilted) optical
axis by ``turn_deg``; and a move along the optical axis, away from the target, by ``height_mm``.
Frames are OpenCV's camera frame (x right, y down in the image, z along the optical axis).

:meth:`ViewSpec.camera_motion` is that motion as a 4x4 transform (the new camera frame in the square
pose's), which a session turns into robot moves and a twin into the target's pose in the camera.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["ViewSpec", "plan_views", "rotation_about"]

FloatArray = npt.NDArray[np.float64]


def rotation_about(axis: Sequence[float], angle_deg: float) -> FloatArray:
    """Rotation matrix about a unit ``axis`` by ``angle_deg`` (right-handed), 3x3."""
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    t = math.radians(angle_deg)
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(t) * k + (1.0 - math.cos(t)) * (k @ k))


@dataclass(frozen=True)
class ViewSpec:
    """One view, as a motion of the camera from the square pose (see the module's docstring).

    ``group`` numbers the orientations: views of one group differ only by ``height_mm`` (a move along the
    optical axis), which lets known heights set the focal length's scale (``station.camcal.calibrate``).
    """

    tilt_deg: float = 0.0
    azimuth_deg: float = 0.0
    turn_deg: float = 0.0
    height_mm: float = 0.0
    shift_mm: tuple[float, float] = (0.0, 0.0)
    group: int = 0

    def __post_init__(self) -> None:
        values = (self.tilt_deg, self.azimuth_deg, self.turn_deg, self.height_mm, *self.shift_mm)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"a view's angles and distances must be finite, got {self}")
        if not 0.0 <= self.tilt_deg < 60.0:
            raise ValueError(f"tilt_deg must be in [0, 60), got {self.tilt_deg}")

    def camera_motion(self, working_distance_mm: float) -> FloatArray:
        """The camera frame after the motion, in the square pose's camera frame, 4x4 (mm)."""
        if not working_distance_mm > 0:
            raise ValueError(f"working_distance_mm must be > 0, got {working_distance_mm}")
        az = math.radians(self.azimuth_deg)
        tilt = rotation_about((math.cos(az), math.sin(az), 0.0), self.tilt_deg)
        R = tilt @ rotation_about((0.0, 0.0, 1.0), self.turn_deg)
        focus = np.array([self.shift_mm[0], self.shift_mm[1], working_distance_mm])
        origin = focus - tilt @ np.array([0.0, 0.0, working_distance_mm])
        origin = origin - self.height_mm * R[:, 2]
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R, origin
        return T


def plan_views(
    *,
    square_turns_deg: Sequence[float] = (0.0, 90.0, 180.0, 270.0),
    heights_mm: Sequence[float] = (0.0, -1.5, 1.5),
    square_passes: int = 26,
    tilts_deg: Sequence[float] = (12.0,),
    azimuths: int = 24,
    tilted_turns_deg: Sequence[float] = (0.0, 45.0, 90.0, 135.0),
) -> list[ViewSpec]:
    """The views of a camera calibration: square ones at several heights, tilted ones around.

    Each square turn is one group: its heights in the order given, then the heights other than the one
    nearest focus again, until they are taken ``square_passes`` times: each view is a move of the arm,
    whose jitter the passes average down (the distance sensor reads each height). The square views out
    of the markers' depth of field are followed from the view nearest focus
    (``station.camcal.follow_target``), so the default starts each turn in focus. Each tilt at each of
    ``azimuths`` directions and each turn is a group of one view in focus (the principal point and the
    distortion).
    The heights must stay where the corners can be followed (+/-1.5 mm for the standard target behind an
    f/4 1X macro lens: ``TARGET.md``). Returned grouped, in an order a robot takes with little motion.
    """
    if azimuths < 1:
        raise ValueError(f"azimuths must be >= 1, got {azimuths}")
    if square_passes < 1:
        raise ValueError(f"square_passes must be >= 1, got {square_passes}")
    if not heights_mm:
        raise ValueError("heights_mm needs at least one value")
    focus = min(heights_mm, key=abs)
    others = [h for h in heights_mm if h != focus]
    views: list[ViewSpec] = []
    group = 0
    for turn in square_turns_deg:
        heights = [*heights_mm, *(others * (square_passes - 1))]
        views += [ViewSpec(0.0, 0.0, turn, h, group=group) for h in heights]
        group += 1
    for tilt in tilts_deg:
        for k in range(azimuths):
            for turn in tilted_turns_deg:
                views.append(ViewSpec(tilt, 360.0 * k / azimuths, turn, 0.0, group=group))
                group += 1
    return views
