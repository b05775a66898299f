"""The calibration plan's configurations and the runner's Align / MoveOffset actions (no sim session)."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import BaseModel, ValidationError

from drivers.crs_a465._safety import MotionGuard, SafetyLimits
from sim.station import sim_safety, taught_artifacts_mm, taught_normals, taught_turns_deg
from sim.world import World
from station.kinds.calibration.params import CalibrationCell, CalibrationParams
from station.kinds.calibration.plan import CALIBRATION, LIMIT_MARGIN_DEG, quantised, unwrap_near
from station.kinematics import Kinematics
from station.plans import (
    Align,
    AlignInput,
    Capture,
    CaptureResult,
    Correction,
    MoveJoints,
    MoveOffset,
    PlanContext,
    PlanError,
    ReferencePose,
    Step,
)
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeDistanceSensor, FakeRobot, FakeStation
from station.vision import MeasureParams

REFERENCE = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)


@pytest.fixture(scope="module")
def world() -> World:
    return World()


@pytest.fixture(scope="module")
def cell(world: World) -> CalibrationCell:
    return CalibrationCell(
        kinematics=Kinematics(tool=world.kinematics.tool),
        artifacts_mm=tuple(taught_artifacts_mm(world)),
        artifact_turns_deg=tuple(taught_turns_deg(world)),
        artifact_normals=tuple(taught_normals(world)),
        working_distance_mm=68.0,
        focal_px=6800.0,
        sensor_mount=np.eye(4),
        max_step_deg=30.0,
        reference_joints_deg=REFERENCE,
    )


def context(cell: CalibrationCell | None) -> PlanContext:
    return PlanContext(measure_params=MeasureParams(), reference_joints_deg=REFERENCE, cell=cell)


def test_each_configuration_looks_square_at_its_artifact_from_inside_the_limits(
    cell: CalibrationCell,
) -> None:
    configs = CALIBRATION.configurations(CalibrationParams(), cell)
    kin = cell.kinematics
    # the table's level artifact: one joint solution; the four tilted ones: four each (shoulder x wrist)
    assert len(configs) == 4 * (1 + 4 * 4)
    assert {c.placement for c in configs} == {0, 1, 2, 3, 4}
    for c in configs:
        assert kin.within_limits(c.joints_deg, margin_deg=LIMIT_MARGIN_DEG - 1e-6)
        pose = kin.forward(c.joints_deg)
        up = np.asarray(cell.artifact_normals[c.placement])  # type: ignore[index]
        up = up / np.linalg.norm(up)
        assert pose[:3, 2] @ -up == pytest.approx(1.0, abs=1e-6)  # the optical axis along -normal
        seen = pose[:3, 3] + 68.0 * pose[:3, 2]
        assert np.allclose(seen, cell.artifacts_mm[c.placement], atol=0.002)
    # the wrist bends sideways at the tilted artifacts: joint 4 takes values away from 0 and 180
    j4 = {round(abs(c.joints_deg[3])) for c in configs}
    assert any(10 < a < 170 for a in j4)


def test_every_planned_move_passes_the_drivers_keepout_and_step_checks(
    cell: CalibrationCell, world: World
) -> None:
    guard = MotionGuard(SafetyLimits(**sim_safety(world)))
    steps = list(CALIBRATION.steps(CalibrationParams(), context(cell)))
    previous = np.array(REFERENCE)
    moves = 0
    for step in steps:
        base = previous
        for action in step.actions:
            if isinstance(action, MoveJoints):
                planned = action.target_deg
                target = base = np.array(planned)
            elif isinstance(action, MoveOffset):
                planned = action.offset_deg
                target = base + np.array(planned)
            else:
                continue
            assert planned == quantised(planned)  # at the controller's 0.001 deg
            guard.plan_single_joint_moves(
                previous, [(i + 1, float(d)) for i, d in enumerate(target - previous)]
            )
            previous = target
            moves += 1
    assert moves > len(steps) * 5


def test_in_view_motions_shift_the_camera_by_the_asked_amount(cell: CalibrationCell) -> None:
    params = CalibrationParams(placements=[1], turns_deg=[-20.0], inview_mm=1.2)
    step = next(iter(CALIBRATION.steps(params, context(cell))))
    config = CALIBRATION.configurations(params, cell)[0]
    kin = cell.kinematics
    here = kin.forward(config.joints_deg)
    offsets = [a.offset_deg for a in step.actions if isinstance(a, MoveOffset)]
    assert len(offsets) == 5
    assert offsets[-1] == (0.0,) * 6  # four shifts, then back for the return capture
    for off in offsets[:4]:
        moved = kin.forward(np.add(config.joints_deg, off))
        shift = np.linalg.solve(here, np.append(moved[:3, 3], 1.0))[:3]
        assert math.hypot(shift[0], shift[1]) == pytest.approx(1.2, abs=0.01)
        assert abs(shift[2]) < 0.01


@pytest.mark.parametrize(
    ("values", "needle"),
    [
        ({"turns_deg": [45.0]}, "45.0 deg from a multiple of 90"),
        ({"turns_deg": []}, "at least one turn"),
        ({"inview_mm": 5.0}, "inview_mm"),
    ],
)
def test_bad_parameters_are_refused_with_the_reason(values: dict[str, Any], needle: str) -> None:
    with pytest.raises(ValidationError, match=needle):
        CalibrationParams.model_validate(values)


def test_a_placement_outside_the_cell_or_no_cell_is_a_plan_error(cell: CalibrationCell) -> None:
    with pytest.raises(PlanError, match="placement 9 is not in the cell"):
        list(CALIBRATION.steps(CalibrationParams(placements=[9]), context(cell)))
    with pytest.raises(PlanError, match=r"\[calibration\] section"):
        list(CALIBRATION.steps(CalibrationParams(), context(None)))


def test_unwrap_keeps_a_joint_on_the_side_of_its_seed() -> None:
    limits = np.array([(-180.0, 180.0)] * 6)
    assert unwrap_near([0, 0, 0, 0, 0, -179.9], [0, 0, 0, 0, 0, 179.5], limits)[5] == pytest.approx(-179.9)
    assert unwrap_near([0, 0, 0, 0, 0, -170.0], [0, 0, 0, 0, 0, 175.0], limits)[5] == pytest.approx(-170.0)
    limits[5] = (-270.0, 270.0)
    assert unwrap_near([0, 0, 0, 0, 0, -170.0], [0, 0, 0, 0, 0, 175.0], limits)[5] == pytest.approx(190.0)


# --------------------------------------------------------------------------- Align in the runner


class _AlignParams(BaseModel):
    corrections: list[list[float]] = []  # joint targets the corrector asks for, in turn
    translation_mm: float = 0.5


@dataclass
class _AlignPlan:
    """One step: move, Align (corrections from the params), capture, an in-view offset, capture."""

    seen: list[AlignInput]
    name: str = "align-test"
    Params: type[BaseModel] = _AlignParams
    needs: frozenset[str] = frozenset({"robot", "camera"})

    def steps(self, params: _AlignParams, ctx: PlanContext) -> Iterator[Step]:
        queue = [tuple(c) for c in params.corrections]

        def correct(seen: AlignInput) -> Correction | None:
            self.seen.append(seen)
            return Correction(queue.pop(0), params.translation_mm) if queue else None

        start = (1.0, 30.0, 60.0, 0.0, 90.0, 0.0)
        actions = (
            MoveJoints(start),
            Align(correct=correct, planned_deg=start, meta={"kind": "align"}, settle_s=0.0),
            Capture(1, {"kind": "pose"}),
            MoveOffset((0.5, 0.0, 0.0, 0.0, 0.0, 0.0)),
            Capture(1, {"kind": "inview"}),
        )
        yield Step(0, "configuration", actions, {})

    def resume_prelude(self, params: _AlignParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: _AlignParams, ctx: PlanContext) -> ReferencePose | None:
        return None

    def analyse(
        self, params: _AlignParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        return {"kinds": [c.meta.get("kind") for c in captures], "frames": [c.frame_index for c in captures]}


def run_align(
    tmp_path: Path, robot: FakeRobot | None = None, **params: Any
) -> tuple[SessionRunner, FakeStation, _AlignPlan, Record]:
    fake = FakeStation(robot=robot or FakeRobot(), distance_sensor=FakeDistanceSensor(68.02))
    plan = _AlignPlan([])
    record = Record(tmp_path)
    runner = SessionRunner(record, plan, _AlignParams(**params), devices=fake.devices())
    runner.run()
    return runner, fake, plan, record


def test_align_measures_moves_within_bounds_and_offsets_start_from_the_aligned_pose(tmp_path: Path) -> None:
    corrected = (1.2, 30.1, 60.0, 0.0, 90.0, 0.0)
    runner, fake, plan, record = run_align(tmp_path, corrections=[list(corrected)])
    with record:
        assert runner.state is SessionState.SUCCEEDED, runner.error
        moves = [c[0] for c in fake.robot.calls_of("move_joints")]
        # the planned move, the correction, then the in-view offset from the corrected pose
        assert moves[1] == corrected
        assert moves[2] == pytest.approx((1.7, 30.1, 60.0, 0.0, 90.0, 0.0))
        # the corrector saw the measured crossing, the distance reading and the image's size
        assert plan.seen[0].center_px is not None
        assert plan.seen[0].z_mm == pytest.approx(68.02)
        assert plan.seen[0].image_size == (640, 480)
        # every frame stored, the align frames too, each with its own index
        assert runner.results is not None
        assert runner.results["kinds"] == ["align", "align", "pose", "inview"]
        assert runner.results["frames"] == [0, 1, 2, 3]
        step = record.steps(runner.session_id or "")[0]
        assert step.data["corrections"][0]["translation_mm"] == 0.5


def test_a_correction_beyond_its_bounds_is_refused_and_the_step_skipped(tmp_path: Path) -> None:
    runner, fake, _, record = run_align(tmp_path, corrections=[[4.0, 30.0, 60.0, 0.0, 90.0, 0.0]])
    with record:
        assert runner.state is SessionState.SUCCEEDED, runner.error
        moves = [c[0] for c in fake.robot.calls_of("move_joints")]
        assert moves == [(1.0, 30.0, 60.0, 0.0, 90.0, 0.0)]  # only the planned move: nothing beyond bounds
        step = record.steps(runner.session_id or "")[0]
        assert "exceeds its bounds" in step.data["skipped"]
        assert "3.000 deg" in step.data["skipped"]
    runner, fake, _, record = run_align(
        tmp_path / "far", corrections=[[1.1, 30.0, 60.0, 0.0, 90.0, 0.0]], translation_mm=2.5
    )
    with record:
        assert [c[0] for c in fake.robot.calls_of("move_joints")] == [(1.0, 30.0, 60.0, 0.0, 90.0, 0.0)]
        assert "2.500 mm" in record.steps(runner.session_id or "")[0].data["skipped"]


def test_a_correction_that_fails_validation_is_not_sent(tmp_path: Path) -> None:
    # within the Align's bounds, but joint 3 beyond the arm's limit: check_move refuses, nothing is sent
    limits = [(-175.0, 175.0), (-90.0, 110.0), (-110.0, 61.0)] + [(-180.0, 180.0)] * 3
    runner, fake, _, record = run_align(
        tmp_path, FakeRobot(limits_deg=limits), corrections=[[1.0, 30.0, 61.5, 0.0, 90.0, 0.0]]
    )
    with record:
        assert runner.state is SessionState.FAILED
        assert "joint 3 target 61.5 deg is outside" in (runner.error or "")
        assert [c[0] for c in fake.robot.calls_of("move_joints")] == [(1.0, 30.0, 60.0, 0.0, 90.0, 0.0)]
