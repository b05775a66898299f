"""The ``calibration`` kind's parameter model and its view of the cell (``PlanContext.cell``)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.kinematics import Kinematics, transform
from station.plans import PlanError
from station.ruler_config import RulerConfig

if TYPE_CHECKING:
    from station.vision import MeasureParams

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class CalibrationCell:
    """What the plan knows of the cell: the nominal arm with the camera as tool, where the artifacts are,
    the optics and the distance sensor's mount (sensor frame in the camera frame; beam along its +z)."""

    kinematics: Kinematics
    artifacts_mm: tuple[tuple[float, float, float], ...]
    artifact_turns_deg: tuple[float, ...] | None
    artifact_normals: tuple[tuple[float, float, float], ...] | None
    working_distance_mm: float
    focal_px: float
    principal_px: tuple[float, float] | None = None
    sensor_mount: FloatArray | None = None
    max_step_deg: float = 30.0
    reference_joints_deg: tuple[float, ...] | None = None
    rulers: tuple[RulerConfig, ...] = ()

    def depth_from_sensor(self, z_mm: float) -> float:
        """The artifact plane's depth along the optical axis from a sensor reading (beam parallel to the
        axis, plane square to it: a tilt t of the plane moves it by the mount's lateral offset x tan t)."""
        if self.sensor_mount is None:
            raise PlanError("the cell has no distance sensor mount")
        R, t = self.sensor_mount[:3, :3], self.sensor_mount[:3, 3]
        return float(R[2, 2] * z_mm + t[2])


def calibration_cell_from_config(
    config: Mapping[str, Any], measure_params: MeasureParams
) -> CalibrationCell | None:
    """The calibration plan's cell from a station configuration (a ``StationConfig`` dumped as JSON, or the
    configuration snapshot a session recorded); ``None`` without a ``[calibration]`` section, a robot or
    a distance sensor."""
    from station.config import CalibrationConfig, SensorMount

    robot = config.get("robot")
    sensor = config.get("distance_sensor")
    if not config.get("calibration") or not robot or not sensor:
        return None
    cal = CalibrationConfig.model_validate(config["calibration"])
    mount = SensorMount.model_validate(sensor.get("mount") or {})
    safety = robot.get("safety") or {}
    offset = tuple(float(v) for v in safety.get("camera_offset_mm", (0.0, 0.0, 0.0)))
    focal = cal.working_distance_mm / cal.pixel_mm
    principal: tuple[float, float] | None = None
    if measure_params.camera_matrix is not None:
        focal = float(measure_params.camera_matrix[0][0])
        principal = (float(measure_params.camera_matrix[0][2]), float(measure_params.camera_matrix[1][2]))
    reference = robot.get("reference_joints_deg")
    return CalibrationCell(
        kinematics=Kinematics(tool=transform(np.eye(3), offset)),
        artifacts_mm=tuple((float(x), float(y), float(z)) for x, y, z in cal.artifacts_mm),
        artifact_turns_deg=tuple(cal.artifact_turns_deg or [0.0] * len(cal.artifacts_mm)),
        artifact_normals=None
        if cal.artifact_normals is None
        else tuple((float(a), float(b), float(c)) for a, b, c in cal.artifact_normals),
        working_distance_mm=cal.working_distance_mm,
        focal_px=focal,
        principal_px=principal,
        sensor_mount=mount.matrix(),
        max_step_deg=float(safety.get("max_step_deg", 30.0)),
        reference_joints_deg=None if reference is None else tuple(float(a) for a in reference),
        rulers=tuple(cal.rulers),
    )


class CalibrationParams(BaseModel):
    """Parameters of a calibration session (defaults: the full configuration, about 5 minutes on the
    simulated station)."""

    model_config = ConfigDict(extra="forbid")

    placements: list[int] | None = Field(
        None, description="indices of the cell's artifacts_mm to use (default: all of them)"
    )
    turns_deg: list[float] = Field(
        default_factory=lambda: [-20.0, 70.0, 160.0, 250.0],
        description="camera turns about the optical axis from where the cross looks square (deg), each"
        " within 30 deg of a multiple of 90",
    )
    solutions: int = Field(4, ge=1, le=8, description="joint solutions per camera pose (wrist, shoulder)")
    inview_mm: float = Field(1.2, ge=0.0, le=2.0, description="in-view camera shift along x and y (mm)")
    inview_turn_deg: float = Field(0.0, ge=0.0, le=30.0, description="in-view turn about the axis (deg)")
    focus_tolerance_mm: float = Field(0.05, gt=0, le=0.5, description="|distance - working distance| (mm)")
    centre_tolerance_mm: float = Field(0.05, gt=0, le=1.0, description="crossing to image centre (mm)")
    speed_pct: int = Field(50, ge=1, le=100)
    settle_s: float = Field(0.25, ge=0.0, le=10.0)
    holdout_fraction: float = Field(0.25, ge=0.0, lt=0.9, description="configurations held out of the fit")
    seed: int = Field(0, description="which configurations are held out")
    loss: Literal["linear", "soft_l1", "huber", "cauchy"] = Field(
        "linear",
        description="the fit's loss: linear (least squares), or a robust one under which a capture whose"
        " residual is beyond f_scale sigmas (a mismeasured one) pulls less",
    )
    f_scale: float = Field(3.0, gt=0, le=100, description="a robust loss's scale, in sigmas (5 um)")
    rulers: list[int] | None = Field(
        None,
        description="the cell's rulers ([[calibration.rulers]] indices) to capture along; default: all of"
        " them when placements is not given, none when it is",
    )
    ruler_positions_mm: list[float] = Field(
        default_factory=lambda: [5.0, 15.0, 45.0, 95.0, 155.0, 205.0, 245.0],
        description="where along each ruler the camera looks (mm): frames 10 to 240 mm apart",
    )
    ruler_turns_deg: list[float] = Field(
        default_factory=lambda: [0.0, 90.0, 180.0, 270.0],
        description="the camera's turns about its axis over a ruler, from the image's x along +s (deg)",
    )
    ruler_solutions: int = Field(2, ge=1, le=8, description="joint solutions per ruler frame and turn")
    ruler_depth_offsets_mm: list[float] = Field(
        default_factory=lambda: [-1.5, 1.5],
        description="frames off the capture plane, further along the optical axis (mm)",
    )
    ruler_depth_positions_mm: list[float] = Field(
        default_factory=lambda: [45.0, 205.0], description="where along each ruler those frames are (mm)"
    )
    ruler_lean_deg: float = Field(
        15.0, ge=0.0, le=30.0, description="the camera's lean from square in the leaning frames (0: none)"
    )
    ruler_lean_positions_mm: list[float] = Field(
        default_factory=lambda: [15.0, 95.0, 205.0], description="where along each ruler it leans (mm)"
    )

    @field_validator(
        "ruler_positions_mm", "ruler_depth_positions_mm", "ruler_lean_positions_mm", "ruler_depth_offsets_mm"
    )
    @classmethod
    def _finite_mm(cls, v: list[float]) -> list[float]:
        if not all(math.isfinite(x) and abs(x) <= 2000.0 for x in v):
            raise ValueError(f"positions and offsets along a ruler must be finite, within 2000 mm, got {v}")
        return v

    @field_validator("ruler_turns_deg")
    @classmethod
    def _ruler_turns(cls, v: list[float]) -> list[float]:
        if not v or not all(math.isfinite(t) for t in v):
            raise ValueError(f"ruler_turns_deg needs at least one finite turn, got {v}")
        return v

    @field_validator("turns_deg")
    @classmethod
    def _turns(cls, v: list[float]) -> list[float]:
        if not v:
            raise ValueError("turns_deg needs at least one turn")
        for t in v:
            if not math.isfinite(t):
                raise ValueError(f"turns_deg must be finite, got {t}")
            off = (t + 45.0) % 90.0 - 45.0
            if abs(off) > 30.0:
                raise ValueError(
                    f"turn {t} deg is {abs(off):.1f} deg from a multiple of 90: precise mode measures the"
                    " cross within 30 deg of its image axes; use turns within +/-30 deg of 0, 90, 180, 270"
                )
        return v
