"""How things sit on the arm: the camera on the flange, the distance sensor beside the camera.

One model per mounting, a translation AND a rotation, so that a camera rolled or tilted on its bracket
can be described. Rotations are ``rotation_deg = (rx, ry, rz)``: ``R = rot_z(rz) @ rot_y(ry) @ rot_x(rx)``
(about the parent's fixed x, then y, then z axes).

* :class:`CameraMount`: the camera frame (OpenCV's: x right, y down in the image, z along the optical
  axis, origin at the centre of projection) in the flange frame. The same model gives the calibration its
  nominal camera frame and the keep-out its camera body (``body``: a cylinder along the optical axis) and
  the lens front (``front_mm`` ahead of the origin), the point kept above the table plane.
* :class:`SensorMount`: the distance sensor in the camera frame, its +z axis the beam, its origin the
  reference point its readings start from; ``body`` is its head.

Before issue 23 the camera's mounting was ``[robot] safety.camera_offset_mm``, a translation only:
:func:`camera_mount_of` still reads it (no rotation), and refuses a configuration that gives both and
disagrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

__all__ = [
    "LEGACY_CAMERA_OFFSET_KEY",
    "CameraMount",
    "MountBody",
    "MountConflictError",
    "SensorMount",
    "camera_mount_of",
    "robot_safety_fields",
    "rotation_xyz_deg",
]

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]

LEGACY_CAMERA_OFFSET_KEY = "camera_offset_mm"
"""The pre-issue-23 key (in ``[robot] safety``): the camera's front in the flange frame, no rotation."""


class MountConflictError(ValueError):
    """The configuration describes the camera's mounting twice, differently."""


def rotation_xyz_deg(rotation_deg: Sequence[float]) -> FloatArray:
    """3x3 ``rot_z(rz) @ rot_y(ry) @ rot_x(rx)`` for ``rotation_deg = (rx, ry, rz)`` in degrees."""
    rx, ry, rz = (math.radians(float(a)) for a in rotation_deg)
    cx, sx, cy, sy, cz, sz = (
        math.cos(rx),
        math.sin(rx),
        math.cos(ry),
        math.sin(ry),
        math.cos(rz),
        math.sin(rz),
    )
    Rx = np.array([[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]])
    Ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
    Rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return np.asarray(Rz @ Ry @ Rx, dtype=np.float64)


def _finite3(v: Vec3) -> Vec3:
    if not all(math.isfinite(a) for a in v):
        raise ValueError(f"must be finite numbers, got {v}")
    return v


class MountBody(BaseModel):
    """A body as a cylinder along the mounted frame's z axis, from ``z_from_mm`` to ``z_to_mm`` (mm, in
    that frame), radius ``radius_mm``: for the keep-out."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    radius_mm: float = Field(gt=0, le=500)
    z_from_mm: float
    z_to_mm: float

    @model_validator(mode="after")
    def _ordered(self) -> MountBody:
        if not (math.isfinite(self.z_from_mm) and math.isfinite(self.z_to_mm)):
            raise ValueError("z_from_mm and z_to_mm must be finite")
        if self.z_from_mm >= self.z_to_mm:
            raise ValueError(f"z_from_mm ({self.z_from_mm}) must be below z_to_mm ({self.z_to_mm})")
        return self


class _Mount(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    translation_mm: Vec3 = (0.0, 0.0, 0.0)
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("translation_mm", "rotation_deg")
    @classmethod
    def _finite(cls, v: Vec3) -> Vec3:
        return _finite3(v)

    def matrix(self) -> FloatArray:
        """4x4 pose of the mounted frame in its parent's (mm)."""
        T = np.eye(4)
        T[:3, :3] = rotation_xyz_deg(self.rotation_deg)
        T[:3, 3] = self.translation_mm
        return T

    def body_segment_mm(self, body: MountBody) -> tuple[FloatArray, FloatArray]:
        """The body's axis ends in the parent's frame (mm)."""
        T = self.matrix()
        ends = T[:3, :] @ np.array([[0.0, 0.0], [0.0, 0.0], [body.z_from_mm, body.z_to_mm], [1.0, 1.0]])
        return ends[:, 0], ends[:, 1]


class CameraMount(_Mount):
    """The camera frame in the flange frame (see the module's docstring), its lens front and body.

    ``front_mm``: the lens front, that far ahead of the camera frame's origin along the optical axis (the
    point the keep-out holds ``min_camera_height_mm`` above the table). ``body``: the camera and lens as
    a cylinder along the optical axis (camera frame); default 30 mm in radius from the front back to
    the flange's plane.
    """

    translation_mm: Vec3 = (0.0, 0.0, 100.0)
    front_mm: float = Field(0.0, ge=-500, le=500)
    body: MountBody | None = None

    def front_point_mm(self) -> FloatArray:
        """The lens front in the flange frame (mm)."""
        return np.asarray(self.matrix()[:3, :] @ np.array([0.0, 0.0, self.front_mm, 1.0]), dtype=np.float64)

    def body_or_default(self) -> MountBody:
        """``body``, or a 30 mm cylinder from the lens front back along the optical axis to the flange's
        distance."""
        if self.body is not None:
            return self.body
        back = max(float(np.linalg.norm(self.translation_mm)), 1.0)
        return MountBody(radius_mm=30.0, z_from_mm=self.front_mm - back, z_to_mm=self.front_mm)


class SensorMount(_Mount):
    """Where a distance sensor sits in the camera (tool) frame: its reference point (the origin its
    distances are measured from) at ``translation_mm`` and its axes turned by ``rotation_deg``; its +z
    axis is the beam. ``body``: its head, for the keep-out (in the sensor's frame; none by default).

    The default is beside the camera, beam parallel to the optical axis.
    """

    translation_mm: Vec3 = (30.0, 0.0, 0.0)
    body: MountBody | None = None

    def point_mm(self, z_mm: float) -> FloatArray:
        """The point a reading ``z_mm`` measured, in the camera frame (mm): ``mount @ (0, 0, z, 1)``."""
        return np.asarray(self.matrix()[:3, :] @ np.array([0.0, 0.0, float(z_mm), 1.0]), dtype=np.float64)

    def reading_at_plane_mm(self, distance_mm: float) -> float:
        """What the sensor reads on a plane square to the optical axis ``distance_mm`` in front of the
        camera (e.g. the working distance: the reading that means "in focus")."""
        T = self.matrix()
        beam_z = float(T[2, 2])
        if beam_z <= 1e-9:
            raise ValueError("the sensor's beam does not point forward along the optical axis")
        return (float(distance_mm) - float(T[2, 3])) / beam_z


def camera_mount_of(config: Mapping[str, Any]) -> CameraMount:
    """The camera's mounting from a station configuration as JSON (``StationConfig.model_dump(mode=
    "json")`` or a session's recorded snapshot): ``[camera] mount``, else the old ``[robot]
    safety.camera_offset_mm`` (a translation: no rotation, the front at the origin), else the default.

    Raises :class:`MountConflictError` when both are given and do not describe the same front point.
    """
    camera = config.get("camera") or {}
    robot = config.get("robot") or {}
    safety = robot.get("safety") or {}
    raw = camera.get("mount") if isinstance(camera, Mapping) else None
    legacy = safety.get(LEGACY_CAMERA_OFFSET_KEY) if isinstance(safety, Mapping) else None
    mount = CameraMount.model_validate(raw) if raw is not None else None
    if legacy is not None:
        offset = tuple(float(v) for v in legacy)
        if len(offset) != 3 or not all(math.isfinite(v) for v in offset):
            raise MountConflictError(
                f"[robot] safety.{LEGACY_CAMERA_OFFSET_KEY} must be 3 numbers, got {legacy}"
            )
        if mount is None:
            return CameraMount(translation_mm=(offset[0], offset[1], offset[2]))
        if not np.allclose(mount.front_point_mm(), offset, atol=1e-6):
            raise MountConflictError(
                f"[camera] mount puts the lens front at {np.round(mount.front_point_mm(), 3).tolist()} mm in"
                f" the flange frame, [robot] safety.{LEGACY_CAMERA_OFFSET_KEY} at {list(offset)}:"
                f" describe the camera once, in [camera] mount, and remove {LEGACY_CAMERA_OFFSET_KEY}"
            )
    return mount if mount is not None else CameraMount()


def robot_safety_fields(
    safety: dict[str, Any], camera: CameraMount, sensor: SensorMount | None
) -> dict[str, Any]:
    """``safety`` (a robot's ``[robot] safety``) completed from the mounts: ``camera_offset_mm`` (the lens
    front in the flange frame) and ``carried`` (the camera body and the sensor head as capsules in the
    flange frame, after any the configuration lists itself)."""
    out = dict(safety)
    out[LEGACY_CAMERA_OFFSET_KEY] = tuple(float(v) for v in camera.front_point_mm())
    carried = list(out.get("carried") or [])
    body = camera.body_or_default()
    a, b = camera.body_segment_mm(body)
    carried.append(
        {"name": "camera body", "start_mm": tuple(a), "end_mm": tuple(b), "radius_mm": body.radius_mm}
    )
    if sensor is not None and sensor.body is not None:
        head = sensor.body
        in_flange = camera.matrix() @ sensor.matrix()
        ends = in_flange[:3, :] @ np.array(
            [[0.0, 0.0], [0.0, 0.0], [head.z_from_mm, head.z_to_mm], [1.0, 1.0]]
        )
        carried.append(
            {
                "name": "distance sensor head",
                "start_mm": tuple(float(v) for v in ends[:, 0]),
                "end_mm": tuple(float(v) for v in ends[:, 1]),
                "radius_mm": head.radius_mm,
            }
        )
    out["carried"] = carried
    return out
