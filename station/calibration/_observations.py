"""What the identification reads: the captures of a calibration session and the station's known constants.

An :class:`Observation` is one capture: the encoder readings, the measured pixel of the groove crossing
and the distance sensor's reading (a ruler's frames are ``RulerObservation``, ``_ruler_observations``). A
:class:`CalibrationSetup` holds what is known before the fit: the camera's intrinsics, the sensor's mount,
the nominal DH table and tool, the approximate artifact placements and the rulers' (:class:`RulerPlacement`).
Both are plain, immutable data; :func:`observation_arrays` stacks observations into the arrays the
vectorised model works on.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import numpy as np
import numpy.typing as npt

from station.kinematics import A465_DH, JOINTS, DHRow

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

ObservationKind = Literal["pose", "inview"]


class CalibrationError(ValueError):
    """Input the identification cannot use (bad observation, missing constant, too little data)."""


@dataclass(frozen=True)
class Observation:
    """One capture of a calibration session.

    Attributes
    ----------
    joints_deg
        The six encoder readings at the capture (deg).
    center_px
        ``(u, v)``: the measured pixel of the groove crossing (0-based, x right, y down).
    z_mm
        The distance sensor's reading: from its emitter along its beam to the artifact's top plane
        (mm); None when the capture has no reading.
    configuration
        A robot posture reached by a planned move; the small in-view motions from it share the id.
    placement
        Which artifact (or artifact position) the camera sees.
    kind
        ``"pose"`` (the capture at the configuration) or ``"inview"`` (a small motion from it).
    """

    joints_deg: tuple[float, float, float, float, float, float]
    center_px: tuple[float, float]
    z_mm: float | None
    configuration: int
    placement: int
    kind: ObservationKind = "pose"

    def __post_init__(self) -> None:
        try:  # lists and numpy arrays become tuples of floats
            object.__setattr__(self, "joints_deg", tuple(float(v) for v in self.joints_deg))
            object.__setattr__(self, "center_px", tuple(float(v) for v in self.center_px))
            if self.z_mm is not None:
                object.__setattr__(self, "z_mm", float(self.z_mm))
        except (TypeError, ValueError) as exc:
            raise CalibrationError(f"an observation's values must be numbers: {exc}") from exc
        if len(self.joints_deg) != JOINTS or not all(math.isfinite(v) for v in self.joints_deg):
            raise CalibrationError(
                f"joints_deg must be {JOINTS} finite angles (deg), got {self.joints_deg!r}"
            )
        if len(self.center_px) != 2 or not all(math.isfinite(v) for v in self.center_px):
            raise CalibrationError(f"center_px must be 2 finite pixel coordinates, got {self.center_px!r}")
        if self.z_mm is not None and not (math.isfinite(self.z_mm) and self.z_mm > 0):
            raise CalibrationError(f"z_mm must be a positive distance (mm) or None, got {self.z_mm!r}")
        if self.kind not in ("pose", "inview"):
            raise CalibrationError(f"kind must be 'pose' or 'inview', got {self.kind!r}")


@dataclass(frozen=True)
class CameraModel:
    """The camera's pinhole intrinsics (px), known before the fit.

    ``working_distance_mm`` converts pixel residuals to mm (``working_distance_mm / focal_px`` mm per
    pixel at the focal plane, where the captures are taken).
    """

    focal_px: float
    principal_px: tuple[float, float]
    width: int
    height: int
    working_distance_mm: float = 68.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.focal_px) and self.focal_px > 0):
            raise CalibrationError(f"focal_px must be > 0, got {self.focal_px!r}")
        if not (self.working_distance_mm > 0):
            raise CalibrationError(f"working_distance_mm must be > 0, got {self.working_distance_mm!r}")
        if self.width < 1 or self.height < 1:
            raise CalibrationError(f"image size must be positive, got {self.width}x{self.height}")

    @property
    def mm_per_px(self) -> float:
        """Scale of the focal plane (mm per pixel)."""
        return self.working_distance_mm / self.focal_px

    @classmethod
    def ideal(cls, width: int, height: int, *, px_per_mm: float, working_distance_mm: float) -> CameraModel:
        """An ideal pinhole: principal point at the image centre, ``focal = working distance x scale``."""
        return cls(
            focal_px=px_per_mm * working_distance_mm,
            principal_px=((width - 1) / 2.0, (height - 1) / 2.0),
            width=width,
            height=height,
            working_distance_mm=working_distance_mm,
        )


def _unit(value: npt.ArrayLike, name: str) -> FloatArray:
    v = np.asarray(value, dtype=float)
    norm = float(np.linalg.norm(v)) if v.shape == (3,) else math.nan
    if not (math.isfinite(norm) and norm > 0):
        raise CalibrationError(f"{name} must be a non-zero, finite 3-vector, got {value!r}")
    return np.asarray(v / norm, dtype=float)


@dataclass(frozen=True)
class RulerPlacement:
    """Where a ruler lies in the cell, as taught (base frame): the fit starts here.

    Attributes
    ----------
    origin_mm
        Graduation 0's point on the ruler's axis (``t = 0``), on its top surface (mm).
    direction
        The direction of increasing position along the ruler (``+s``).
    normal
        The top surface's upward normal (toward the camera that reads it); +z (level) by default.

    Notes
    -----
    The ruler's frame (``station/vision/RULER.md``): ``s`` along it, ``t`` across, ``n = s x t`` into
    the ruler (away from the camera), so that a camera square on it sees ``t`` at +90 deg from ``s`` in
    the image's handedness, as ``measure_ruler`` reports.
    """

    origin_mm: tuple[float, float, float]
    direction: tuple[float, float, float]
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        origin = tuple(float(v) for v in self.origin_mm)
        if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
            raise CalibrationError(
                f"a ruler's origin_mm must be 3 finite coordinates, got {self.origin_mm!r}"
            )
        object.__setattr__(self, "origin_mm", origin)
        s = _unit(self.direction, "a ruler's direction")
        n = _unit(self.normal, "a ruler's normal")
        if abs(float(s @ n)) > 0.2:
            raise CalibrationError(
                f"a ruler's direction {self.direction!r} must lie in its surface, nearly square to its normal"
                f" {self.normal!r} (within 11 deg); teach both again"
            )

    def frame(self) -> FloatArray:
        """3x3 rotation with columns ``s, t, n`` (base frame): ``s`` the direction made square to the
        normal, ``n`` the downward normal, ``t = n x s``."""
        down = -_unit(self.normal, "normal")
        s = _unit(self.direction, "direction")
        s = s - (s @ down) * down
        s = s / np.linalg.norm(s)
        return np.column_stack([s, np.cross(down, s), down])


def _checked_4x4(value: npt.ArrayLike, name: str) -> FloatArray:
    T = np.array(value, dtype=float)
    if T.shape != (4, 4) or not np.allclose(T[3], [0, 0, 0, 1]) or not np.all(np.isfinite(T)):
        raise CalibrationError(f"{name} must be a finite 4x4 homogeneous transform, got shape {T.shape}")
    if not np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9):
        raise CalibrationError(f"{name}'s rotation is not orthonormal")
    return T


@dataclass(frozen=True)
class CalibrationSetup:
    """The constants of a calibration: known (camera, sensor mount) or nominal (DH, tool, artifacts).

    Attributes
    ----------
    camera
        The camera's intrinsics.
    sensor_mount
        4x4 pose of the distance sensor in the camera frame (mm); its +z axis is the beam.
    nominal_tool
        4x4 camera frame in the flange frame (mm).
    artifacts
        Approximate crossing position of each placement, base frame (mm), by placement id.
    artifact_normals
        The nominal normal of each placement's top plane (base frame); +z (level) when absent.
    nominal_dh
        The nominal DH table (the A465's by default).
    rulers
        Each ruler's taught placement, by ruler id (none by default).
    """

    camera: CameraModel
    sensor_mount: FloatArray
    nominal_tool: FloatArray
    artifacts: Mapping[int, tuple[float, float, float]]
    artifact_normals: Mapping[int, tuple[float, float, float]] = field(default_factory=dict)
    nominal_dh: tuple[DHRow, ...] = A465_DH
    rulers: Mapping[int, RulerPlacement] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "sensor_mount", _checked_4x4(self.sensor_mount, "sensor_mount"))
        object.__setattr__(self, "nominal_tool", _checked_4x4(self.nominal_tool, "nominal_tool"))
        if len(self.nominal_dh) != JOINTS:
            raise CalibrationError(f"nominal_dh must have {JOINTS} rows, got {len(self.nominal_dh)}")
        if not self.artifacts:
            raise CalibrationError("artifacts must give the approximate position of at least one placement")
        for k, p in self.artifacts.items():
            if len(p) != 3 or not all(math.isfinite(v) for v in p):
                raise CalibrationError(f"artifacts[{k}] must be 3 finite coordinates (mm), got {p!r}")
        for k, n in self.artifact_normals.items():
            if len(n) != 3 or not math.isfinite(float(np.linalg.norm(n))) or float(np.linalg.norm(n)) == 0:
                raise CalibrationError(f"artifact_normals[{k}] must be a non-zero 3-vector, got {n!r}")
        for k, r in self.rulers.items():
            if not isinstance(r, RulerPlacement):
                raise CalibrationError(f"rulers[{k}] must be a RulerPlacement, got {type(r).__name__}")

    @property
    def placements(self) -> tuple[int, ...]:
        """Placement ids, sorted."""
        return tuple(sorted(self.artifacts))

    def normal(self, placement: int) -> FloatArray:
        """The nominal unit normal of a placement's plane (base frame)."""
        n = np.asarray(self.artifact_normals.get(placement, (0.0, 0.0, 1.0)), dtype=float)
        return np.asarray(n / np.linalg.norm(n), dtype=float)


@dataclass(frozen=True)
class ObservationArrays:
    """Observations stacked for the vectorised model (N observations)."""

    joints_deg: FloatArray  # (N, 6)
    center_px: FloatArray  # (N, 2)
    z_mm: FloatArray  # (N,), NaN where there is no reading
    has_z: npt.NDArray[np.bool_]  # (N,)
    configuration: IntArray  # (N,)
    placement_index: IntArray  # (N,), index into CalibrationSetup.placements
    is_pose: npt.NDArray[np.bool_]  # (N,)

    def __len__(self) -> int:
        return int(self.joints_deg.shape[0])


def observation_arrays(observations: Sequence[Observation], placements: Sequence[int]) -> ObservationArrays:
    """Stack ``observations``; ``placements`` (sorted ids) maps each placement id to its index."""
    if not observations:
        raise CalibrationError("no observations: a calibration needs captures")
    index = {k: i for i, k in enumerate(placements)}
    unknown = sorted({o.placement for o in observations} - set(index))
    if unknown:
        raise CalibrationError(
            f"observations see placements {unknown} that the setup does not list; add their approximate"
            " positions to CalibrationSetup.artifacts"
        )
    z = np.array([np.nan if o.z_mm is None else o.z_mm for o in observations], dtype=float)
    return ObservationArrays(
        joints_deg=np.array([o.joints_deg for o in observations], dtype=float),
        center_px=np.array([o.center_px for o in observations], dtype=float),
        z_mm=z,
        has_z=np.isfinite(z),
        configuration=np.array([o.configuration for o in observations], dtype=np.int64),
        placement_index=np.array([index[o.placement] for o in observations], dtype=np.int64),
        is_pose=np.array([o.kind == "pose" for o in observations], dtype=bool),
    )
