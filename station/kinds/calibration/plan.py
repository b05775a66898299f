"""The ``calibration`` plan: capture what identifies the arm's kinematic errors.

For each artifact placement of the cell (``[calibration] artifacts_mm``), for each turn of the camera about
its optical axis (within +/-30 deg of a multiple of 90 deg: precise mode measures the cross there) and
for each joint solution the nominal inverse kinematics gives within the joint limits (wrist flips,
shoulder and elbow combinations), one **configuration**:

1. the arm travels there through a lift pose (upper arm and forearm upright: the camera high above every
   artifact) and descends, every move split into steps within the driver's step limit;
2. :class:`~station.plans.Align` brings the camera to its working distance (the distance sensor's reading,
   within ``focus_tolerance_mm``) and the crossing to the image centre (within ``centre_tolerance_mm``):
   measured, data-dependent corrections along the camera's axes (focus first when the image is too
   blurred to measure), each move at most 2 mm, never more than 2 deg per joint from the planned pose,
   each checked with ``check_move`` by the runner before it is sent;
3. a ``pose`` capture, then small in-view motions (camera shifts of ``inview_mm`` along its x and y and
   turns of ``inview_turn_deg`` about its axis, as joint offsets from the aligned pose) each captured
   (``inview``), and the pose again (``return``: the arm's repeatability, from which the relative error's
   floor is estimated).

Every planned move is a pure function of the parameters and the cell, so pre-flight checks the whole
session before anything moves. Captures carry ``configuration``, ``placement``, ``turn_deg``,
``solution`` and ``kind`` in their metadata; the joints (encoders) and the distance sensor's reading are
recorded with each. Identification is offline (:mod:`station.calibration`) and re-runs on any stored
session (``station calibrate SESSION``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from station.arm_route import quantised, split_move, travel, unwrap_near
from station.kinds.calibration.analysis import analyse_calibration
from station.kinds.calibration.gates import calibration_checks
from station.kinds.calibration.params import CalibrationCell, CalibrationParams, calibration_cell_from_config
from station.kinds.calibration.ruler_plan import (
    RulerConfiguration,
    ruler_configurations,
    ruler_steps,
    selected_rulers,
)
from station.kinematics import LOOK_DOWN, KinematicsError, rot_z, square_on, transform
from station.plans import (
    Align,
    AlignInput,
    AlignSkippedError,
    Capture,
    CaptureResult,
    Correction,
    MoveJoints,
    MoveOffset,
    PlanContext,
    PlanError,
    ReferencePose,
    SetSpeed,
    Settle,
    Step,
)

if TYPE_CHECKING:
    from station.vision import MeasureParams

FloatArray = npt.NDArray[np.float64]

LIMIT_MARGIN_DEG = 2.5
"""How far inside its limits every joint of a planned pose stays: room for the measured corrections."""

MAX_CORRECTION_MM = 1.9
"""The longest single focus/re-centring move (within the runner's 2 mm bound); longer ones go in parts."""


@dataclass(frozen=True)
class Configuration:
    """One planned configuration: where the camera should be and the joints that put it there."""

    index: int
    placement: int
    turn_deg: float
    solution: int
    joints_deg: tuple[float, ...]
    camera_pose: FloatArray


def _cell(ctx: PlanContext) -> CalibrationCell:
    if ctx.cell is None:
        raise PlanError(
            "a calibration session needs the cell's [calibration] section (artifacts_mm, "
            "working_distance_mm, pixel_mm), a robot with camera_offset_mm in its safety settings and a "
            "distance sensor with its mount; see the README's calibration section"
        )
    cell: CalibrationCell = ctx.cell
    return cell


class CalibrationPlan:
    name = "calibration"
    Params = CalibrationParams
    needs = frozenset({"robot", "camera", "distance_sensor"})

    def table_content(self, params: CalibrationParams) -> str | None:
        """The artifact's cross on the X-Y table when the session visits it (placement 0, the table's
        artifact; default: every placement), else nothing in particular (``station.table_content``)."""
        return "cross" if params.placements is None or 0 in params.placements else None

    def scale_check(self, params: CalibrationParams, devices: Any) -> str:
        """``station.scale_preflight``'s mode: a session along the cell's rulers identifies the camera's
        magnification itself (and its gate compares it with the groove widths), so a camera model that
        disagrees with the grooves only warns; without rulers the identification takes the model as
        exact, and the disagreement refuses the session."""
        cal = getattr(getattr(devices, "config", None), "calibration", None)
        return "warn" if selected_rulers(params, len(cal.rulers) if cal is not None else 0) else "fail"

    def cell_from_config(
        self, config: Mapping[str, Any], measure_params: MeasureParams
    ) -> CalibrationCell | None:
        """The cell of a station configuration (``PlanContext.cell``): the live station's, or the one a
        stored session recorded (a re-analysis: its artifacts, optics and sensor mount, as the session
        analysed them)."""
        return calibration_cell_from_config(config, measure_params)

    # ---------------------------------------------------------------- configurations

    def configurations(self, params: CalibrationParams, cell: CalibrationCell) -> list[Configuration]:
        """Every configuration the session visits, in order (placement by placement)."""
        placements = (
            params.placements if params.placements is not None else list(range(len(cell.artifacts_mm)))
        )
        for p in placements:
            if not 0 <= p < len(cell.artifacts_mm):
                raise PlanError(
                    f"placement {p} is not in the cell: artifacts_mm has {len(cell.artifacts_mm)} entries"
                )
        kin = cell.kinematics
        out: list[Configuration] = []
        for p in placements:
            crossing = np.asarray(cell.artifacts_mm[p], dtype=float)
            square = cell.artifact_turns_deg[p] if cell.artifact_turns_deg else 0.0
            up = np.asarray(
                cell.artifact_normals[p] if cell.artifact_normals else (0.0, 0.0, 1.0), dtype=float
            )
            up /= np.linalg.norm(up)
            here: list[tuple[int, float, tuple[float, ...], FloatArray]] = []
            for turn in params.turns_deg:
                R = square_on(up) @ LOOK_DOWN @ rot_z(math.radians(square + turn))
                pose = transform(R, crossing + cell.working_distance_mm * up)
                try:
                    sols = kin.inverse_all(pose)
                except KinematicsError:
                    sols = []
                # room for the measured corrections (2 deg): a wrist flip of the A465 with the camera
                # square to the artifact puts joint 4 on its +/-180 deg limit
                sols = [q for q in sols if kin.within_limits(q, margin_deg=LIMIT_MARGIN_DEG)]
                # solutions numbered by branch (shoulder, elbow, wrist), whatever the turn: the signs of
                # joints 2/3 and whether joint 5 is negative; the upright-arm ones first
                sols.sort(key=lambda s: (abs(s[1]) + abs(s[2]), s[4] < 0, abs(s[3])))
                for k, q in enumerate(sols[: params.solutions]):
                    here.append((k, float(turn), tuple(float(a) for a in q), pose))
            if not here:
                raise PlanError(
                    f"placement {p} at {cell.artifacts_mm[p]} mm: no joint solution within the limits puts "
                    "the camera over it at the working distance; move the artifact or drop the placement"
                )
            # one branch at a time, turning the camera in between: the arm travels through the lift pose
            # only when it changes branch or placement
            here.sort(key=lambda h: (h[0], params.turns_deg.index(h[1])))
            for k, turn, joints, camera in here:
                out.append(Configuration(len(out), p, turn, k, quantised(joints), camera))
        return out

    def ruler_configurations(
        self, params: CalibrationParams, cell: CalibrationCell
    ) -> list[RulerConfiguration]:
        """Every frame the session takes along the cell's rulers, after the crossings' configurations
        (``ruler_plan``; none for a cell without rulers)."""
        return ruler_configurations(params, cell, len(self.configurations(params, cell)))

    def _inview_offsets(
        self, params: CalibrationParams, cell: CalibrationCell, c: Configuration
    ) -> list[tuple[str, tuple[float, ...]]]:
        """Joint offsets (from the configuration's joints) for the small in-view motions."""
        kin = cell.kinematics
        d, a = params.inview_mm, math.radians(params.inview_turn_deg)
        moves: list[tuple[str, FloatArray]] = []
        if d > 0:
            for name, v in (("+x", (d, 0, 0)), ("-x", (-d, 0, 0)), ("+y", (0, d, 0)), ("-y", (0, -d, 0))):
                moves.append((name, transform(np.eye(3), v)))
        if a > 0:
            for name, ang in (("+turn", a), ("-turn", -a)):
                moves.append((name, transform(rot_z(ang), (0, 0, 0))))
        out = []
        q0 = np.asarray(c.joints_deg)
        for name, M in moves:
            try:
                q = kin.inverse(c.camera_pose @ M, seed_deg=q0)
            except KinematicsError:
                continue
            near = np.asarray(unwrap_near(q, q0, kin.joint_limits_deg))
            off = near - q0
            if np.max(np.abs(off)) > 15.0 or not kin.within_limits(near, margin_deg=LIMIT_MARGIN_DEG):
                continue  # another branch (not a small motion), or too near a joint limit
            out.append((name, quantised(off)))
        return out

    # ---------------------------------------------------------------- steps

    def steps(self, params: CalibrationParams, ctx: PlanContext) -> Iterator[Step]:
        cell = _cell(ctx)
        configs = self.configurations(params, cell)
        step_limit = cell.max_step_deg * 0.9
        previous: tuple[float, ...] | None = ctx.reference_joints_deg or cell.reference_joints_deg
        prev_config: Configuration | None = None
        for c in configs:
            meta = {
                "configuration": c.index,
                "placement": c.placement,
                "turn_deg": c.turn_deg,
                "solution": c.solution,
            }
            moves: list[tuple[float, ...]] = []
            same_branch = (
                prev_config is not None
                and prev_config.placement == c.placement
                and prev_config.solution == c.solution
            )
            if previous is None:
                moves.append(c.joints_deg)
            elif same_branch:
                moves += split_move(previous, c.joints_deg, step_limit)
            else:
                moves += travel(previous, c.joints_deg, step_limit)
            actions: list[Any] = [SetSpeed(params.speed_pct)] if prev_config is None else []
            actions += [MoveJoints(q) for q in moves]
            if params.settle_s:
                actions.append(Settle(params.settle_s))
            actions.append(
                Align(
                    correct=self._corrector(params, cell),
                    planned_deg=c.joints_deg,
                    meta={**meta, "kind": "align"},
                    settle_s=params.settle_s,
                )
            )
            actions.append(Capture(1, {**meta, "kind": "pose"}))
            for name, off in self._inview_offsets(params, cell, c):
                actions.append(MoveOffset(off))
                if params.settle_s:
                    actions.append(Settle(params.settle_s))
                actions.append(Capture(1, {**meta, "kind": "inview", "motion": name}))
            actions.append(MoveOffset((0.0,) * 6))
            if params.settle_s:
                actions.append(Settle(params.settle_s))
            actions.append(Capture(1, {**meta, "kind": "return"}))
            yield Step(
                c.index,
                f"placement {c.placement} turn {c.turn_deg:g} solution {c.solution}",
                tuple(actions),
                meta,
            )
            previous, prev_config = c.joints_deg, c
        yield from ruler_steps(
            params,
            cell,
            self.ruler_configurations(params, cell),
            previous,
            step_limit,
            first=prev_config is None,
        )

    def _corrector(self, params: CalibrationParams, cell: CalibrationCell) -> Any:
        kin = cell.kinematics

        def correct(seen: AlignInput) -> Correction | None:
            if seen.z_mm is None:
                raise AlignSkippedError("no distance reading: the working distance cannot be checked")
            depth = cell.depth_from_sensor(seen.z_mm)
            dz = depth - cell.working_distance_mm
            if seen.center_px is None:
                if abs(dz) <= params.focus_tolerance_mm:
                    raise AlignSkippedError(
                        f"the crossing is not measured here ({seen.error}): configuration skipped"
                    )
                dx = dy = 0.0  # out of focus: focus first (the sensor needs no image), then look again
            else:
                cx, cy = cell.principal_px or ((seen.image_size[0] - 1) / 2.0, (seen.image_size[1] - 1) / 2.0)
                dx = (seen.center_px[0] - cx) * depth / cell.focal_px
                dy = (seen.center_px[1] - cy) * depth / cell.focal_px
                if math.hypot(dx, dy) <= params.centre_tolerance_mm and abs(dz) <= params.focus_tolerance_mm:
                    return None
            step = np.array([dx, dy, dz])
            size = float(np.linalg.norm(step))
            if size > MAX_CORRECTION_MM:  # a long way: go part of it, then measure again
                step *= MAX_CORRECTION_MM / size
            here = kin.forward(seen.joints_deg)
            try:
                q = kin.inverse(here @ transform(np.eye(3), step), seed_deg=seen.joints_deg)
            except KinematicsError as exc:
                raise AlignSkippedError(f"the correction cannot be reached: {exc}") from exc
            near = unwrap_near(q, seen.joints_deg, kin.joint_limits_deg)
            return Correction(quantised(near), float(np.linalg.norm(step)))

        return correct

    def reference_pose(self, params: CalibrationParams, ctx: PlanContext) -> ReferencePose | None:
        """The station's reference pose: the first configuration's travel starts there."""
        ref = ctx.reference_joints_deg or (ctx.cell.reference_joints_deg if ctx.cell is not None else None)
        return None if ref is None else ReferencePose(tuple(float(a) for a in ref))

    def resume_prelude(self, params: CalibrationParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        """From the reference pose (where the session's route brought the arm) to where ``next_step``'s
        travel starts: the previous configuration's planned pose, through the lift poses."""
        ref = self.reference_pose(params, ctx)
        index = int(next_step.meta.get("configuration", 0))
        if ref is None or index == 0:
            return []
        cell = _cell(ctx)
        crossings = self.configurations(params, cell)
        previous: Configuration | RulerConfiguration = (
            crossings[index - 1]
            if index <= len(crossings)
            else self.ruler_configurations(params, cell)[index - 1 - len(crossings)]
        )
        moves = travel(ref.joints_deg, previous.joints_deg, cell.max_step_deg * 0.9)
        meta = {"role": "resume", "configuration": previous.index}
        name = f"resume: to configuration {previous.index}'s pose"
        return [Step(-1, name, (SetSpeed(params.speed_pct), *(MoveJoints(q) for q in moves)), meta)]

    # ---------------------------------------------------------------- analysis

    def analyse(
        self, params: CalibrationParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        cell = _cell(ctx)
        planned = len(self.configurations(params, cell)) + len(self.ruler_configurations(params, cell))
        results = analyse_calibration(params, cell, captures, planned=planned)
        results["checks"] = calibration_checks(results)
        if results.get("scale_calibration") is not None:  # from the rulers: this session wrote it
            results["scale_calibration"]["session_id"] = ctx.session_id
        return results


CALIBRATION = CalibrationPlan()
