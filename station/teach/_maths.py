"""Teaching, the pure part: from what the station reads (joints, a measured crossing, the distance
sensor's readings) and its nominal model (the arm's nominal kinematics with the camera's mounting as the
tool, the camera model, the sensor's mount), the values ``station.toml`` holds for the cell.

Frames: the base frame of the arm; the camera frame is OpenCV's (x right, y down in the image, z along
the optical axis). Every value is what the nominal model makes of the readings: the kinematic
calibration identifies the model's errors later (the taught values need only be close).

* The artifact's plane: sensor points (each reading along the beam, through the mount and the nominal
  camera pose) at a few camera positions, fitted by least squares (:func:`fit_plane`); its upward
  normal is ``artifact_normals``. With the camera squared to the artifact, ``-z`` of the camera is the
  normal too (:func:`normal_of_camera`).
* The crossing: the measured pixel's ray (the lens's distortion undone) met with that plane
  (:func:`crossing_on_plane`): ``artifacts_mm``.
* The square turn: the measured direction of the groove nearest the image's x, carried onto the plane
  and expressed in the frame the calibration plan looks at the artifact from (``square_on(normal) @
  LOOK_DOWN``, whose x is the image's x of a camera square to it with its x along the base's -x):
  ``artifact_turns_deg`` (:func:`square_turn_deg`). The cross looks the same every 90 deg: the taught
  turn is the one within 45 deg of the camera's own turn at teach time.
* The pose that sees the crossing on the principal point, square to the plane (or with the camera's
  current orientation), at the working distance (:func:`pose_to_see`), through the nominal inverse
  kinematics: the reference pose, and the square pose an artifact is taught from.
* The sensor's mount offset along the optical axis from readings at known distances
  (:func:`fit_sensor_offset`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from station.camera_model import CameraIntrinsics
from station.kinematics import LOOK_DOWN, Kinematics, rot_z, square_on, transform

__all__ = [
    "LOOK_DOWN",
    "Plane",
    "SensorOffsetFit",
    "TeachError",
    "camera_ray",
    "crossing_on_plane",
    "fit_plane",
    "fit_sensor_offset",
    "normal_of_camera",
    "pose_to_see",
    "sensor_point",
    "square_on",
    "square_turn_deg",
    "wrist_turns_deg",
]

FloatArray = npt.NDArray[np.float64]


class TeachError(ValueError):
    """The readings cannot give the value asked for (too few, degenerate, out of reach); the message says
    what to do."""


@dataclass(frozen=True)
class Plane:
    """A plane in the base frame: a point on it, its upward unit normal, and the rms of the points it was
    fitted to about it (mm)."""

    point_mm: FloatArray
    normal: FloatArray
    rms_mm: float


def sensor_point(camera_pose: FloatArray, mount: FloatArray, reading_mm: float) -> FloatArray:
    """Where a reading ``reading_mm`` lies in the base frame: ``camera_pose @ mount @ (0, 0, r, 1)``."""
    return np.asarray((camera_pose @ mount @ np.array([0.0, 0.0, float(reading_mm), 1.0]))[:3], dtype=float)


def fit_plane(points_mm: npt.ArrayLike) -> Plane:
    """The least-squares plane of three or more points (N x 3, base frame), its normal pointing up (+z)."""
    p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    if len(p) < 3:
        raise TeachError(f"a plane needs three or more sensor points, got {len(p)}")
    centre = p.mean(axis=0)
    _, s, vt = np.linalg.svd(p - centre)
    if s[1] < 1e-3 * max(s[0], 1e-12):
        raise TeachError("the sensor points lie on a line: read at camera offsets in two directions")
    normal = vt[2] if vt[2][2] >= 0 else -vt[2]
    rms = float(s[2] / math.sqrt(len(p)))
    return Plane(centre, normal / np.linalg.norm(normal), rms)


def normal_of_camera(camera_pose: FloatArray) -> FloatArray:
    """The upward normal of a plane the camera is square to: minus its optical axis."""
    n = -np.asarray(camera_pose, dtype=float)[:3, 2]
    return np.asarray(n / np.linalg.norm(n), dtype=np.float64)


def camera_ray(center_px: Sequence[float], intrinsics: CameraIntrinsics) -> FloatArray:
    """The direction (camera frame, z = 1) of the ray through an image point, the distortion undone."""
    pts = np.array([[[float(center_px[0]), float(center_px[1])]]], dtype=np.float64)
    x, y = cv2.undistortPoints(pts, intrinsics.camera_matrix, intrinsics.dist_coeffs).reshape(2)
    return np.array([float(x), float(y), 1.0])


def crossing_on_plane(
    camera_pose: FloatArray, center_px: Sequence[float], intrinsics: CameraIntrinsics, plane: Plane
) -> FloatArray:
    """Where the ray through ``center_px`` meets ``plane`` (base frame, mm)."""
    origin = camera_pose[:3, 3]
    direction = camera_pose[:3, :3] @ camera_ray(center_px, intrinsics)
    along = float(direction @ plane.normal)
    if abs(along) < 1e-6 * float(np.linalg.norm(direction)):
        raise TeachError("the camera looks along the artifact's plane: square it to the artifact")
    t = float((plane.point_mm - origin) @ plane.normal) / along
    if t <= 0:
        raise TeachError("the artifact's plane is behind the camera: check the sensor's mount and readings")
    return np.asarray(origin + t * direction, dtype=np.float64)


def square_turn_deg(
    camera_pose: FloatArray,
    center_px: Sequence[float],
    rotation_deg: float,
    intrinsics: CameraIntrinsics,
    plane: Plane,
) -> float:
    """The turn (deg) at which the cross looks square (``artifact_turns_deg``): the direction of the
    groove at ``rotation_deg`` in the image (the measurement's, the groove nearest the image's x),
    carried onto the plane, in the frame ``square_on(normal) @ LOOK_DOWN``."""
    r = math.radians(rotation_deg)
    step = 20.0  # px along the groove
    far = (float(center_px[0]) + step * math.cos(r), float(center_px[1]) + step * math.sin(r))
    a = crossing_on_plane(camera_pose, center_px, intrinsics, plane)
    b = crossing_on_plane(camera_pose, far, intrinsics, plane)
    u = (square_on(plane.normal) @ LOOK_DOWN).T @ (b - a)
    return math.degrees(math.atan2(float(u[1]), float(u[0])))


WRIST_BEAM_MAX_DEG = 5.0
"""Largest angle between the sensor's beam and the wrist's axis (joint 6) at which turning the wrist
circles the beam's spot on the plane (``wrist_turns_deg``)."""
WRIST_RADIUS_MIN_MM = 5.0
"""Smallest distance of the beam from the wrist's axis that the circle's readings tilt a plane by."""


def wrist_turns_deg(
    kinematics: Kinematics, joints_deg: npt.ArrayLike, sensor_mount: FloatArray, groove_deg: float
) -> list[float] | None:
    """Turns of joint 6 (deg, from ``joints_deg``, nearest first, within a turn and a quarter either
    way) that put the sensor's spot on the artifact at 45 deg from both grooves (``groove_deg``: the
    measured direction of the groove nearest the image's x), on one of the four diagonals (the first
    four turns: each diagonal once): the beam, parallel to the wrist's axis, circles it. None when the
    beam is not (``WRIST_BEAM_MAX_DEG``) or too close to the axis to circle it (``WRIST_RADIUS_MIN_MM``)."""
    start = np.asarray(joints_deg, dtype=np.float64)
    flange = kinematics.flange(start)
    camera = kinematics.forward(start)
    head = camera @ sensor_mount
    axis = flange[:3, 2]
    beam = head[:3, 2]
    if math.degrees(math.acos(min(1.0, abs(float(axis @ beam))))) > WRIST_BEAM_MAX_DEG:
        return None
    offset = head[:3, 3] - flange[:3, 3]
    if float(np.linalg.norm(offset - (offset @ axis) * axis)) < WRIST_RADIUS_MIN_MM:
        return None
    # which way a turn of joint 6 turns the camera about its optical axis (+1 or -1, for a camera
    # mounted along the wrist)
    turned = start.copy()
    turned[5] += 1.0
    x = camera[:3, :3].T @ kinematics.forward(turned)[:3, 0]
    sign = 1.0 if x[1] >= 0.0 else -1.0
    spot = math.degrees(math.atan2(float(sensor_mount[1, 3]), float(sensor_mount[0, 3])))
    base = (sign * (groove_deg + 45.0 - spot) + 45.0) % 90.0 - 45.0
    return sorted((base + 90.0 * k for k in range(-4, 5)), key=abs)


def pose_to_see(
    joints_deg: Sequence[float],
    nominal: Kinematics,
    crossing_mm: npt.ArrayLike,
    working_distance_mm: float,
    *,
    normal: npt.ArrayLike | None = None,
    turn_deg: float | None = None,
) -> FloatArray:
    """The joints (nearest ``joints_deg``) at which the camera sees ``crossing_mm`` on its optical axis at
    ``working_distance_mm``: square to ``normal`` (keeping the camera's turn about its axis as near as it
    is now, or at ``turn_deg`` in the calibration plan's convention, ``square_on(normal) @ LOOK_DOWN``
    turned about the optical axis), or with the camera's current orientation when ``normal`` is None.
    Raises TeachError when the nominal inverse kinematics has no solution within the limits."""
    here = nominal.forward(np.asarray(joints_deg, dtype=float))
    R = here[:3, :3]
    if normal is not None:
        n = np.asarray(normal, dtype=float)
        n = n / np.linalg.norm(n)
        z = -n
        x = R[:, 0] - (R[:, 0] @ z) * z  # the image's x as near as it is now
        if np.linalg.norm(x) < 1e-6:
            raise TeachError("the camera's x lies along the normal: turn it before squaring")
        x = x / np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        if turn_deg is not None:
            R = square_on(n) @ LOOK_DOWN @ rot_z(math.radians(turn_deg))
    target = np.asarray(crossing_mm, dtype=float) - working_distance_mm * R[:, 2]
    try:
        return nominal.inverse(transform(R, target), seed_deg=joints_deg)
    except ValueError as exc:
        raise TeachError(
            f"the nominal model has no joint solution that sees the crossing so ({exc})"
        ) from exc


@dataclass(frozen=True)
class SensorOffsetFit:
    """The sensor mount's offset along the optical axis (``translation_z_mm``, camera frame), the slope
    of distance against reading that the readings show (``slope``; the mount's says ``expected_slope``),
    and the rms of the fit's residuals (mm)."""

    translation_z_mm: float
    slope: float
    expected_slope: float
    rms_mm: float
    count: int


def fit_sensor_offset(
    distances_mm: Sequence[float], readings_mm: Sequence[float], mount: FloatArray
) -> SensorOffsetFit:
    """The mount's z (camera frame) from readings at known distances of a plane square to the optical axis.

    For such a plane at distance ``D`` from the camera's centre, a beam of direction ``R[:, 2]`` from the
    mount's origin ``t`` reads ``r`` with ``D = t_z + R[2, 2] r`` (``station.camcal.distance_from_sensor``):
    with the configured rotation, ``t_z`` is the mean of ``D - R[2, 2] r``. The slope fitted freely checks
    the rotation (a beam tilted from the axis reads longer).
    """
    D = np.asarray(distances_mm, dtype=np.float64)
    r = np.asarray(readings_mm, dtype=np.float64)
    if D.shape != r.shape or D.size < 3:
        raise TeachError(f"the mount's offset needs three or more (distance, reading) pairs, got {D.size}")
    if float(np.ptp(D)) < 0.5:
        raise TeachError("the distances must span at least 0.5 mm: move the camera along its axis further")
    beam_z = float(np.asarray(mount, dtype=float)[2, 2])
    if beam_z < 0.5:
        raise TeachError("the sensor's beam is more than 60 deg from the optical axis: no offset along it")
    tz = float(np.mean(D - beam_z * r))
    slope, _ = np.polyfit(r, D, 1)
    rms = float(np.sqrt(np.mean((D - (tz + beam_z * r)) ** 2)))
    return SensorOffsetFit(tz, float(slope), beam_z, rms, int(D.size))
