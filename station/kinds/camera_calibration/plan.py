"""The camera calibration as a session (issue 23, item 2): the standard ChArUco target on the X-Y table,
seen from the views of ``station.camcal.plan_views``, the intrinsics fitted by ``calibrate_intrinsics``.

The session starts at the reference pose, which is the *square pose* of the views (the camera square to
the target's centre, in focus). Each view is one step: the camera moved there through the arm's nominal
model (``Kinematics`` with the camera's mounting as its tool; small motions from the reference pose, which
the nominal model gives well enough: the fit needs no view's pose), one frame captured (marked
``"artifact": "target"``: stored, never groove-measured), then the distance sensor read
``sensor_samples`` times (their mean is the view's reading: ``TARGET.md`` assumes averaged readings).

The analysis loads each stored frame, finds the target (``detect_target``; a view where it is not found is
left out and counted), fits the intrinsics with the sensor's readings (the focal lengths' scale from the
square views at several heights) and gates on ``IntrinsicsCalibration.problems()``: the focal lengths
within 0.05 % and the principal point within 1 px at 3 sigma, re-projection under 0.1 px. Only a passed
session writes the station's camera model (``model_file``); a failed one writes nothing.

``scale_check = "skip"``: the pre-flight scale check compares captures with the camera model, which this
session is what makes.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.camcal import (
    CameraCalibrationError,
    ViewSpec,
    calibrate_intrinsics,
    plan_views,
)
from station.camera_model import CameraIntrinsics
from station.kinds.camera_calibration.analysis import Bounds, calibration_results
from station.kinds.camera_calibration.views import find_views
from station.kinematics import Kinematics, UnreachableError, transform
from station.plans import (
    Capture,
    CaptureResult,
    DeviceCheck,
    MoveJoints,
    PlanContext,
    PlanError,
    ReferencePose,
    SetSpeed,
    Settle,
    Step,
)
from station.plans._ruler import ARTIFACT_KEY

#: the capture metadata's value (under ``"artifact"``) of a frame of the calibration target
TARGET = "target"
#: the joints may turn at most this far (plus the view's turn about the optical axis) from the reference
#: pose for a view (deg): a larger swing means the nominal model went through a singularity
MAX_VIEW_SWING_DEG = 30.0
#: the twins of an unreachable tilted view: half a turn more about the axis, and 10 deg short or beyond
TWIN_TURNS_DEG = (0.0, -10.0, 10.0)
#: a square view lower than the one before it is approached from this far below it (mm along the optical
#: axis): every square view is then reached moving away from the target, the joints' backlash on one side
APPROACH_MM = 0.5


class CameraCalibrationParams(BaseModel):
    """Parameters of a camera calibration (defaults: ``plan_views``'s 308 views, ``TARGET.md``)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    heights_mm: list[float] = Field(
        default_factory=lambda: [0.0, -1.5, 1.5],
        description="heights of the square views along the optical axis, from focus (mm; the corners "
        "are followed from the view nearest focus up to +/-1.5 mm at f/4)",
    )
    square_passes: int = Field(
        26,
        ge=1,
        le=100,
        description="times each square turn's heights other than the one nearest focus are taken (each "
        "view a move of the arm: the passes average its jitter down)",
    )
    square_turns_deg: list[float] = Field(
        default_factory=lambda: [-135.0, -45.0, 45.0, 135.0],
        description="turns about the optical axis of the square views (deg), each taken at every height "
        "(default: four a quarter turn apart, none with the wrist's roll on its +/-180 deg limit)",
    )
    tilts_deg: list[float] = Field(
        default_factory=lambda: [12.0], description="tilts of the tilted views (deg, each in (0, 25])"
    )
    azimuths: int = Field(24, ge=1, le=36, description="directions of each tilt")
    tilted_turns_deg: list[float] = Field(
        default_factory=lambda: [0.0, 45.0, 90.0, 135.0], description="turns of each tilted view (deg)"
    )
    sensor_samples: int = Field(10, ge=1, le=100, description="distance readings averaged per view")
    focal_bound_pct: float = Field(
        0.05, gt=0.0, le=5.0, description="the focal lengths' bound (%), met by sigma_k uncertainties"
    )
    principal_bound_px: float = Field(
        1.0, gt=0.0, le=50.0, description="the principal point's bound (px), met by sigma_k uncertainties"
    )
    sigma_k: float = Field(3.0, ge=1.0, le=5.0, description="standard uncertainties that must fit in a bound")
    speed_pct: int = Field(20, ge=1, le=100, description="arm speed (%), under the station's cap")
    settle_s: float = Field(0.2, ge=0.0, le=10.0, description="wait after each move before the frame (s)")

    @field_validator("heights_mm")
    @classmethod
    def _heights(cls, v: list[float]) -> list[float]:
        if len(set(v)) < 2:
            raise ValueError("give at least two different heights: the focal length's scale needs them")
        if not all(math.isfinite(h) and abs(h) <= 3.0 for h in v):
            raise ValueError(f"heights must be finite and within +/-3 mm of focus, got {v}")
        return v

    @field_validator("tilts_deg")
    @classmethod
    def _tilts(cls, v: list[float]) -> list[float]:
        if not v or not all(0.0 < t <= 25.0 for t in v):
            raise ValueError(f"give at least one tilt, each in (0, 25] deg, got {v}")
        return v

    @field_validator("square_turns_deg", "tilted_turns_deg")
    @classmethod
    def _turns(cls, v: list[float]) -> list[float]:
        if not v or not all(math.isfinite(t) and abs(t) <= 360.0 for t in v):
            raise ValueError(f"give at least one turn, each within +/-360 deg, got {v}")
        return v

    def views(self) -> list[ViewSpec]:
        return plan_views(
            square_turns_deg=self.square_turns_deg,
            heights_mm=self.heights_mm,
            square_passes=self.square_passes,
            tilts_deg=self.tilts_deg,
            azimuths=self.azimuths,
            tilted_turns_deg=self.tilted_turns_deg,
        )


@dataclass(frozen=True)
class CameraCell:
    """The plan's view of the station: the nominal arm with the camera's mounting as its tool, the
    reference pose (the square pose), the working distance, the nominal camera's focal length (px), the
    configured camera model's path, and whether a distance sensor is configured."""

    kinematics: Kinematics
    reference_joints_deg: tuple[float, ...] | None
    working_distance_mm: float
    focal_px: float
    camera_model: str | None
    has_sensor: bool
    max_step_deg: float = 30.0


def camera_cell_from_config(config: Mapping[str, Any]) -> CameraCell | None:
    """The cell from a station configuration as JSON; None without a robot or ``[calibration]``."""
    from station.config import CalibrationConfig
    from station.mounts import CameraMount

    robot, camera = config.get("robot"), config.get("camera") or {}
    if not robot or not config.get("calibration"):
        return None
    cal = CalibrationConfig.model_validate(config["calibration"])
    if camera.get("mount"):
        tool = CameraMount.model_validate(camera["mount"]).matrix()
    else:
        offset = (robot.get("safety") or {}).get("camera_offset_mm", (0.0, 0.0, 0.0))
        tool = transform(np.eye(3), [float(v) for v in offset])
    reference = robot.get("reference_joints_deg")
    return CameraCell(
        kinematics=Kinematics(tool=tool),
        reference_joints_deg=None if reference is None else tuple(float(a) for a in reference),
        working_distance_mm=float(cal.working_distance_mm),
        focal_px=float(cal.working_distance_mm / cal.pixel_mm),
        camera_model=None if camera.get("camera_model") is None else str(camera["camera_model"]),
        has_sensor=bool(config.get("distance_sensor")),
        max_step_deg=float((robot.get("safety") or {}).get("max_step_deg", 30.0)),
    )


def _joints(cell: CameraCell, view: ViewSpec) -> tuple[float, ...] | None:
    """The joints that put the camera at ``view`` from the reference pose through the nominal model: of
    the solutions within the limits (by 0.01 deg), the one that swings joints 1-5 least; None when none
    keeps them within :data:`MAX_VIEW_SWING_DEG` of the reference pose (unreachable, or through a
    singularity). Joint 6, the wrist's roll, turns the camera about its axis: the view's turn."""
    assert cell.reference_joints_deg is not None
    start = np.asarray(cell.reference_joints_deg, dtype=np.float64)
    pose = cell.kinematics.forward(start) @ view.camera_motion(cell.working_distance_mm)
    try:
        solutions = cell.kinematics.inverse_all(pose)
    except UnreachableError:
        return None
    best: tuple[float, ...] | None = None
    best_swing = MAX_VIEW_SWING_DEG
    for q in solutions:
        rounded = tuple(round(float(a), 4) for a in q)
        swing = float(np.max(np.abs(np.asarray(rounded[:5]) - start[:5])))
        if swing <= best_swing and cell.kinematics.within_limits(rounded, margin_deg=0.01):
            best, best_swing = rounded, swing
    return best


def _lower_in_group(view: ViewSpec, last: ViewSpec) -> bool:
    """A square view of the same turn as ``last``, below it: approached from below (:data:`APPROACH_MM`)."""
    return (
        view.tilt_deg == 0.0
        and last.tilt_deg == 0.0
        and last.group == view.group
        and (view.height_mm < last.height_mm)
    )


def moves_between(
    start: Sequence[float], target: Sequence[float], max_step_deg: float
) -> list[tuple[float, ...]]:
    """``target`` reached from ``start`` in equal moves none of which turns a joint more than
    ``max_step_deg`` (the robot's largest step): the intermediate joints and ``target`` last."""
    a, b = np.asarray(start, dtype=np.float64), np.asarray(target, dtype=np.float64)
    n = max(1, math.ceil(float(np.max(np.abs(b - a))) / (0.95 * max_step_deg)))
    return [tuple(round(float(v), 4) for v in a + (b - a) * (k / n)) for k in range(1, n)] + [
        tuple(float(v) for v in b)
    ]


def view_joints(cell: CameraCell, view: ViewSpec) -> tuple[ViewSpec, tuple[float, ...]]:
    """The view the arm takes for ``view`` and its joints.

    A tilt the wrist cannot reach (toward the base, the wrist's pitch beyond its limit) is taken as its
    twin: tilted toward the opposite azimuth and turned half a turn more, which shows the camera the
    target at the same angle (its normal in the camera's frame is the same), the pattern turned over; where
    that half turn puts the wrist's roll on its limit, 10 deg short of or beyond it (the target's tilt then
    seen 10 deg round in the image, as good a view). The view taken is the one recorded. PlanError when
    none is reachable."""
    if cell.reference_joints_deg is None:
        raise PlanError("a camera calibration starts at the reference pose: set [robot] reference_joints_deg")
    twins = [
        replace(view, azimuth_deg=(view.azimuth_deg + 180.0) % 360.0, turn_deg=view.turn_deg + 180.0 + d)
        for d in TWIN_TURNS_DEG
    ]
    for candidate in [view, *twins] if view.tilt_deg > 0 else [view]:
        q = _joints(cell, candidate)
        if q is not None:
            return candidate, q
    raise PlanError(
        f"the arm cannot take the view {view} from the reference pose (beyond a joint's limit, or through "
        "a singularity): plan smaller tilts or teach a reference pose with the wrist nearer mid-range"
    )


def reading_uncertainty_mm(samples: Sequence[Sequence[float]]) -> float:
    """A view's reading's standard uncertainty (mm): the sensor's scatter within a view (pooled over the
    views), over the square root of the samples averaged; 1 um when no view has two samples."""
    groups = [np.asarray(z, dtype=np.float64) for z in samples if len(z) >= 2]
    if not groups:
        return 0.001
    dof = sum(len(z) - 1 for z in groups)
    pooled = math.sqrt(sum(float(np.sum((z - z.mean()) ** 2)) for z in groups) / dof)
    return max(pooled / math.sqrt(min(len(z) for z in groups)), 1e-5)


def _read_sensor(samples: int) -> Any:
    """The step's device procedure: the distance sensor read ``samples`` times (mm)."""

    def run(devices: Any) -> dict[str, Any]:
        sensor = devices.distance_sensor
        if sensor is None:
            raise PlanError("a camera calibration needs the distance sensor ([distance_sensor])")
        return {"z_samples_mm": [float(sensor.read_mm()) for _ in range(samples)]}

    return run


class CameraCalibrationPlan:
    name = "camera-calibration"
    Params = CameraCalibrationParams
    needs = frozenset({"robot", "camera", "distance_sensor"})
    #: the pre-flight scale check compares with the camera model, which this session makes
    scale_check = "skip"

    def table_content(self, params: CameraCalibrationParams) -> str:
        """The calibration target on the X-Y table, in the artifact's place (``station.table_content``)."""
        return "target"

    def cell_from_config(self, config: Mapping[str, Any], measure_params: Any) -> CameraCell | None:
        return camera_cell_from_config(config)

    def _cell(self, ctx: PlanContext) -> CameraCell:
        if not isinstance(ctx.cell, CameraCell):
            raise PlanError(
                "a camera calibration needs the station's [calibration] section (working_distance_mm, "
                "pixel_mm) and [robot] reference_joints_deg: give --config FILE"
            )
        return ctx.cell

    def steps(self, params: CameraCalibrationParams, ctx: PlanContext) -> Iterator[Step]:
        cell = self._cell(ctx)
        previous = cell.reference_joints_deg
        last: ViewSpec | None = None
        for i, planned in enumerate(params.views()):
            view, joints = view_joints(cell, planned)
            assert previous is not None  # view_joints refuses a cell without a reference pose
            route = [joints]
            if last is not None and _lower_in_group(view, last):
                route = [view_joints(cell, replace(view, height_mm=view.height_mm - APPROACH_MM))[1], joints]
            moves = []
            for q in route:
                moves += [MoveJoints(m) for m in moves_between(previous, q, cell.max_step_deg)]
                previous = q
            last = view
            meta = {
                ARTIFACT_KEY: TARGET,
                "role": "camera_view",
                "view": i,
                "group": view.group,
                "tilt_deg": view.tilt_deg,
                "azimuth_deg": view.azimuth_deg,
                "turn_deg": view.turn_deg,
                "height_mm": view.height_mm,
            }
            actions: tuple[Any, ...] = (
                *moves,
                Settle(params.settle_s),
                Capture(1, meta),
                DeviceCheck(_read_sensor(params.sensor_samples), "distance readings"),
            )
            if i == 0:
                actions = (SetSpeed(params.speed_pct), *actions)
            yield Step(i, f"view {i}", actions, meta)

    def reference_pose(self, params: CameraCalibrationParams, ctx: PlanContext) -> ReferencePose | None:
        """The reference pose: the camera square to the target's centre, in focus (the views' origin)."""
        ref = ctx.reference_joints_deg
        return None if ref is None else ReferencePose(tuple(float(a) for a in ref))

    def resume_prelude(
        self, params: CameraCalibrationParams, ctx: PlanContext, next_step: Step
    ) -> list[Step]:
        """From the reference pose (where the session's route brought the arm) to the previous view's
        joints, where ``next_step``'s moves start, within the robot's largest step."""
        if next_step.index == 0:
            return []
        cell = self._cell(ctx)
        assert cell.reference_joints_deg is not None  # the steps were planned from it
        _, previous = view_joints(cell, params.views()[next_step.index - 1])
        moves = moves_between(cell.reference_joints_deg, previous, cell.max_step_deg)
        actions: tuple[Any, ...] = (SetSpeed(params.speed_pct), *(MoveJoints(q) for q in moves))
        return [Step(-1, f"resume: to view {next_step.index - 1}", actions, {"role": "resume"})]

    def analyse(
        self, params: CameraCalibrationParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        if ctx.record is None or ctx.session_id is None:
            raise PlanError("a camera calibration is analysed from its record")
        cell = self._cell(ctx)
        record, sid = ctx.record, ctx.session_id
        samples: dict[int, list[float]] = {
            s.index: s.data["z_samples_mm"]
            for s in record.steps(sid)
            if isinstance(s.data.get("z_samples_mm"), list)
        }
        rows = {c.id: c for c in record.captures(sid)}
        taken = [c for c in captures if c.meta.get(ARTIFACT_KEY) == TARGET]
        if not taken:
            raise PlanError("no view of the target was captured: start the calibration again")
        views = find_views(
            taken, lambda c: record.load_image(rows[c.capture_id]), samples, cell.working_distance_mm
        )
        detections, readings, missed = views.detections, views.readings, views.missed
        width, height = taken[0].width, taken[0].height
        guess = CameraIntrinsics(
            np.array(
                [
                    [cell.focal_px, 0.0, (width - 1) / 2.0],
                    [0.0, cell.focal_px, (height - 1) / 2.0],
                    [0, 0, 1],
                ],
                dtype=np.float64,
            ),
            np.zeros(5),
            (width, height),
        )
        try:
            cal = calibrate_intrinsics(
                detections,
                guess=guess,
                readings=readings,
                reading_u_mm=reading_uncertainty_mm(list(samples.values())),
                source={"session": sid},
                pose_only=views.followed,
            )
        except CameraCalibrationError as exc:
            raise PlanError(
                f"the camera could not be calibrated from {len(detections)} of {len(taken)} views: {exc}"
                + (f" (target not found: {'; '.join(missed[:3])})" if missed else "")
            ) from exc
        return calibration_results(
            cal,
            Bounds(params.focal_bound_pct, params.principal_bound_px, params.sigma_k),
            taken=len(taken),
            missed=missed,
            camera_model=cell.camera_model,
            data_dir=Path(record.data_dir),
        )


CAMERA_CALIBRATION = CameraCalibrationPlan()
