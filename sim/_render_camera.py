"""The physical side of the simulated camera: artifact, camera and pose specs, and the homography.

Conventions are stated once, in ``sim.artifact`` (which re-exports everything public here).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields, replace
from typing import Any, TypeVar

import numpy as np

from sim._render_geometry import FloatArray

__all__ = [
    "F4_DEFOCUS_PX_PER_MM",
    "INCH_MM",
    "ArtifactSpec",
    "CameraSpec",
    "Pose",
    "homography_for",
    "pose_for_center_px",
    "spec_from_dict",
]

INCH_MM = 25.4

F4_DEFOCUS_PX_PER_MM = 3.1
"""The blur's growth away from focus for the seed's optics at f/4 (sigma px per mm of depth): a 1X macro
lens (magnification m = 1, working f-number N (1 + m) = 8) spreads a point 1 mm from focus over a disc of
1 mm / 8 = 125 um on the sensor, 12.5 px at the grabber's 10 um/px; a uniform disc of diameter D has a
standard deviation of D / 4 per axis: 3.1 px per mm."""

_T = TypeVar("_T")


def spec_from_dict(cls: type[_T], data: Mapping[str, Any]) -> _T:
    """Build the frozen dataclass ``cls`` from a dict; ValueError naming missing or unknown keys."""
    names = {f.name for f in fields(cls)}  # type: ignore[arg-type]
    missing, unknown = names - set(data), set(data) - names
    if missing or unknown:
        raise ValueError(f"{cls.__name__}: missing keys {sorted(missing)}, unknown keys {sorted(unknown)}")
    return cls(**dict(data))


def _need(ok: bool, message: str) -> None:
    if not ok:
        raise ValueError(message)


@dataclass(frozen=True)
class ArtifactSpec:
    """The physical artifact.

    Attributes
    ----------
    groove_width_mm : float
        True machined width of both grooves, mm (tolerance +0/-0.002 in on the nominal).
    nominal_groove_width_mm : float
        Width on the drawing, mm (what a measurement assumes unless it calibrates the scale).
    corner_radius_mm : float
        Radius of each land's rounded corner at the crossing (seed Figure 7), mm; 0 for sharp.
    texture_seed : int
        Seed of the surface features (streaks, scratches, glints), which are fixed to the artifact.
    """

    groove_width_mm: float = INCH_MM / 32
    nominal_groove_width_mm: float = INCH_MM / 32
    corner_radius_mm: float = 0.1
    texture_seed: int = 0

    def __post_init__(self) -> None:
        _need(
            0 < self.groove_width_mm < 10,
            f"groove_width_mm must be in (0, 10) mm, got {self.groove_width_mm}",
        )
        _need(0 < self.nominal_groove_width_mm < 10, "nominal_groove_width_mm must be in (0, 10) mm")
        _need(0 <= self.corner_radius_mm < self.groove_width_mm, "corner_radius_mm must be in [0, width)")

    def to_dict(self) -> dict[str, Any]:
        """All fields as a JSON-ready dict."""
        return asdict(self)


@dataclass(frozen=True)
class CameraSpec:
    """The camera: sensor size and the scale of the focal plane.

    Attributes
    ----------
    width, height : int
        Image size, px.
    px_per_mm : float
        Image scale of the focal plane, px/mm (100 px/mm = 10 um per pixel).
    working_distance_mm : float
        Distance from the pinhole to the focal plane, mm (sets the strength of perspective).
    """

    width: int = 640
    height: int = 480
    px_per_mm: float = 100.0
    working_distance_mm: float = 68.0

    def __post_init__(self) -> None:
        _need(self.width >= 16 and self.height >= 16, "camera width and height must be >= 16 px")
        _need(self.px_per_mm > 0 and self.working_distance_mm > 0, "camera scale and distance must be > 0")

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``, the numpy shape of an image."""
        return (self.height, self.width)

    @property
    def focal_px(self) -> float:
        """Focal length, px."""
        return self.px_per_mm * self.working_distance_mm

    @property
    def principal_point(self) -> tuple[float, float]:
        """Image of the optical axis ``(x, y)``, px: the image centre."""
        return ((self.width - 1) / 2.0, (self.height - 1) / 2.0)

    def matrix(self) -> FloatArray:
        """Intrinsic matrix K, 3x3."""
        cx, cy = self.principal_point
        return np.array([[self.focal_px, 0.0, cx], [0.0, self.focal_px, cy], [0.0, 0.0, 1.0]])

    def to_dict(self) -> dict[str, Any]:
        """All fields as a JSON-ready dict."""
        return asdict(self)


def _rot(axis: int, deg: float) -> FloatArray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(3)
    m[i, i] = m[j, j] = c
    m[i, j], m[j, i] = -s, s
    return m


@dataclass(frozen=True)
class Pose:
    """Physical pose of the artifact relative to the camera (see the module's conventions).

    Attributes
    ----------
    x_mm, y_mm : float
        Artifact origin relative to the optical axis, camera axes (x right, y down), mm.
    rotation_deg : float
        In-plane rotation: the u axis points along image ``(cos, sin)``; positive is clockwise on screen.
    tilt_x_deg, tilt_y_deg : float
        Small tilts of the artifact plane about the camera x and y axes, deg.
    z_mm : float
        Offset of the origin along the optical axis from the focal plane (positive: farther), mm.
    """

    x_mm: float
    y_mm: float
    rotation_deg: float = 0.0
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0
    z_mm: float = 0.0

    def __post_init__(self) -> None:
        for f in fields(self):
            _need(math.isfinite(getattr(self, f.name)), f"pose {f.name} must be finite")
        _need(abs(self.tilt_x_deg) < 45 and abs(self.tilt_y_deg) < 45, "pose tilts must be within 45 deg")

    def rotation_matrix(self) -> FloatArray:
        """R, 3x3: artifact axes (u, v, normal) in camera axes."""
        return _rot(0, self.tilt_x_deg) @ _rot(1, self.tilt_y_deg) @ _rot(2, self.rotation_deg)

    def displaced(self, du_mm: float, dv_mm: float) -> Pose:
        """The artifact moved by ``(du, dv)`` mm in its own frame (within its plane)."""
        step = self.rotation_matrix()[:, :2] @ np.array([du_mm, dv_mm], dtype=np.float64)
        return replace(
            self,
            x_mm=self.x_mm + float(step[0]),
            y_mm=self.y_mm + float(step[1]),
            z_mm=self.z_mm + float(step[2]),
        )

    def to_dict(self) -> dict[str, float]:
        """All fields as a JSON-ready dict."""
        return {k: float(v) for k, v in asdict(self).items()}


def pose_for_center_px(
    cx: float,
    cy: float,
    *,
    rotation_deg: float = 0.0,
    tilt_x_deg: float = 0.0,
    tilt_y_deg: float = 0.0,
    z_mm: float = 0.0,
    camera: CameraSpec = CameraSpec(),
) -> Pose:
    """The pose whose artifact origin (groove crossing) images at pixel ``(cx, cy)``."""
    depth = camera.working_distance_mm + z_mm
    _need(depth > 0, "z_mm puts the artifact behind the camera")
    ppx, ppy = camera.principal_point
    return Pose(
        x_mm=(cx - ppx) * depth / camera.focal_px,
        y_mm=(cy - ppy) * depth / camera.focal_px,
        rotation_deg=rotation_deg,
        tilt_x_deg=tilt_x_deg,
        tilt_y_deg=tilt_y_deg,
        z_mm=z_mm,
    )


def homography_for(pose: Pose, camera: CameraSpec = CameraSpec()) -> FloatArray:
    """Homography artifact mm -> image px, 3x3, scaled so that ``H[2, 2] = 1``."""
    r = pose.rotation_matrix()
    t = np.array([pose.x_mm, pose.y_mm, camera.working_distance_mm + pose.z_mm])
    _need(t[2] > 0, "the artifact origin is behind the camera")
    h = camera.matrix() @ np.column_stack([r[:, 0], r[:, 1], t])
    return np.asarray(h / h[2, 2])
