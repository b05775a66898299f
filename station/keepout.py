"""Keep-out volumes: what the arm must never touch, and the distance maths a path check runs on.

Two kinds of volume, both in millimetres:

* **Fixed volumes** (:class:`KeepOutBox`, :class:`KeepOutCylinder`) in the arm's base frame: the cell's
  fixtures (the X-Y table, angle blocks, the bench artifacts' plates). A box is centred at ``center_mm``
  with edges ``size_mm`` along its own axes, turned by ``rotation_deg`` (about the base's x, then y, then
  z: ``R = Rz @ Ry @ Rx``, as the mounts); a cylinder stands on ``base_mm`` along ``axis`` for
  ``height_mm`` with radius ``radius_mm``.
* **Carried bodies** (:class:`CarriedBody`): what the arm carries, as capsules (a segment and a radius) in
  the flange frame: the wrist and flange, the camera body, the distance sensor's head. A capsule encloses
  a cylinder of the same radius and ends, so the check is conservative.

The check itself (:func:`first_contact`) runs on sampled poses: every carried capsule is covered by
spheres (spacing at most its radius, each sphere's radius enlarged so that their union holds the
capsule), and a sphere touches a volume when its centre is within its radius plus the margin. The
caller chooses the margin: the clearance wanted, plus half the largest motion of any carried point
between two samples of a path (then nothing between the samples can reach the volume either).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.mounts import rotation_xyz_deg

__all__ = [
    "CarriedBody",
    "Contact",
    "KeepOut",
    "KeepOutBox",
    "KeepOutCylinder",
    "body_spheres",
    "first_contact",
    "volume_distance",
]

FloatArray = npt.NDArray[np.float64]
Vec3 = tuple[float, float, float]


def _finite(v: tuple[float, ...]) -> tuple[float, ...]:
    if not all(math.isfinite(c) for c in v):
        raise ValueError(f"must be finite numbers, got {v}")
    return v


class KeepOutBox(BaseModel):
    """A box the arm's bodies must stay clear of, in the base frame (mm, deg)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    shape: Literal["box"] = "box"
    name: str = Field(min_length=1, description="what it is (said in a refusal)")
    center_mm: Vec3
    size_mm: Vec3 = Field(description="edge lengths along the box's own x, y, z")
    rotation_deg: Vec3 = (0.0, 0.0, 0.0)

    @field_validator("center_mm", "rotation_deg")
    @classmethod
    def _finite(cls, v: Vec3) -> Vec3:
        return _finite(v)  # type: ignore[return-value]

    @field_validator("size_mm")
    @classmethod
    def _positive(cls, v: Vec3) -> Vec3:
        if not all(math.isfinite(c) and c > 0 for c in v):
            raise ValueError(f"size_mm must be three positive lengths, got {v}")
        return v


class KeepOutCylinder(BaseModel):
    """A cylinder the arm's bodies must stay clear of, in the base frame (mm)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    shape: Literal["cylinder"] = "cylinder"
    name: str = Field(min_length=1, description="what it is (said in a refusal)")
    base_mm: Vec3 = Field(description="the centre of its bottom face")
    axis: Vec3 = Field((0.0, 0.0, 1.0), description="direction from the bottom face to the top")
    radius_mm: float = Field(gt=0)
    height_mm: float = Field(gt=0)

    @field_validator("base_mm")
    @classmethod
    def _finite(cls, v: Vec3) -> Vec3:
        return _finite(v)  # type: ignore[return-value]

    @field_validator("axis")
    @classmethod
    def _direction(cls, v: Vec3) -> Vec3:
        if not all(math.isfinite(c) for c in v) or math.hypot(*v) < 1e-9:
            raise ValueError(f"axis must be a non-zero direction, got {v}")
        return v


KeepOut = Annotated[KeepOutBox | KeepOutCylinder, Field(discriminator="shape")]
"""A fixed volume: ``shape = "box"`` or ``"cylinder"``."""


class CarriedBody(BaseModel):
    """A capsule the arm carries, in the flange frame: the segment ``start_mm``-``end_mm``, radius
    ``radius_mm`` (mm)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field(min_length=1)
    start_mm: Vec3
    end_mm: Vec3
    radius_mm: float = Field(ge=0)

    @field_validator("start_mm", "end_mm")
    @classmethod
    def _finite(cls, v: Vec3) -> Vec3:
        return _finite(v)  # type: ignore[return-value]

    def reach_mm(self) -> float:
        """The farthest any point of it lies from the flange's origin."""
        return max(math.hypot(*self.start_mm), math.hypot(*self.end_mm)) + self.radius_mm


def volume_distance(volume: KeepOutBox | KeepOutCylinder, points_mm: npt.ArrayLike) -> FloatArray:
    """Distance (mm) from each point (N x 3, base frame) to ``volume``; 0 inside it."""
    p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)
    if isinstance(volume, KeepOutBox):
        R = rotation_xyz_deg(volume.rotation_deg)
        local = (p - np.asarray(volume.center_mm)) @ R  # = R.T @ (p - c), row by row
        excess = np.maximum(np.abs(local) - np.asarray(volume.size_mm) / 2.0, 0.0)
        return np.asarray(np.linalg.norm(excess, axis=1), dtype=np.float64)
    axis = np.asarray(volume.axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    rel = p - np.asarray(volume.base_mm)
    along = rel @ axis
    radial = np.linalg.norm(rel - along[:, None] * axis, axis=1)
    beyond_ends = np.maximum(np.maximum(-along, along - volume.height_mm), 0.0)
    beyond_side = np.maximum(radial - volume.radius_mm, 0.0)
    return np.asarray(np.hypot(beyond_ends, beyond_side), dtype=np.float64)


@dataclass(frozen=True)
class BodySpheres:
    """Spheres covering carried bodies: centres in the flange frame (homogeneous, S x 4), radii (S),
    and which body each belongs to (S, an index into ``names``)."""

    centres: FloatArray
    radii: FloatArray
    body: npt.NDArray[np.int64]
    names: tuple[str, ...]


def body_spheres(bodies: Sequence[CarriedBody]) -> BodySpheres:
    """Spheres whose union holds each capsule: along its segment at a spacing of at most its radius (or
    5 mm for a thin one), each enlarged to ``sqrt(r^2 + (spacing / 2)^2)``."""
    centres: list[FloatArray] = []
    radii: list[float] = []
    owner: list[int] = []
    for k, b in enumerate(bodies):
        a, e = np.asarray(b.start_mm, dtype=np.float64), np.asarray(b.end_mm, dtype=np.float64)
        length = float(np.linalg.norm(e - a))
        spacing = max(b.radius_mm, 5.0)
        n = max(1, math.ceil(length / spacing))
        step = length / n
        for t in np.linspace(0.0, 1.0, n + 1):
            centres.append(np.append(a + t * (e - a), 1.0))
            radii.append(math.hypot(b.radius_mm, step / 2.0))
            owner.append(k)
    return BodySpheres(
        np.array(centres, dtype=np.float64).reshape(-1, 4),
        np.array(radii, dtype=np.float64),
        np.array(owner, dtype=np.int64),
        tuple(b.name for b in bodies),
    )


@dataclass(frozen=True)
class Contact:
    """The first sampled pose at which a carried body comes within the margin of a fixed volume."""

    pose_index: int
    body: str
    volume: str
    clearance_mm: float
    """The sphere's surface to the volume (negative: inside it)."""


def first_contact(
    flanges: npt.ArrayLike,
    spheres: BodySpheres,
    volumes: Sequence[KeepOutBox | KeepOutCylinder],
    *,
    margin_mm: float,
) -> Contact | None:
    """The first pose (of ``flanges``, P x 4 x 4, base frame) at which any sphere comes within
    ``margin_mm`` of any volume, or None. Vectorised over poses and spheres."""
    if not volumes or spheres.radii.size == 0:
        return None
    F = np.asarray(flanges, dtype=np.float64).reshape(-1, 4, 4)
    points = np.einsum("pij,sj->psi", F, spheres.centres)[:, :, :3]  # P x S x 3
    n_poses, n_spheres = points.shape[:2]
    worst: Contact | None = None
    for volume in volumes:
        gap = volume_distance(volume, points.reshape(-1, 3)).reshape(n_poses, n_spheres) - spheres.radii
        hit = gap < margin_mm
        if not hit.any():
            continue
        pose = int(np.flatnonzero(hit.any(axis=1))[0])
        sphere = int(np.argmin(gap[pose]))
        if worst is None or pose < worst.pose_index:
            worst = Contact(pose, spheres.names[spheres.body[sphere]], volume.name, float(gap[pose, sphere]))
    return worst
