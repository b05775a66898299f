"""Every session starts at its plan's reference pose: the runner makes the arm's route there (from where it is
commanded) the session's first motion, checked in pre-flight; a validation, which never moves the arm, is
refused when it is elsewhere; a stop returns along the same route (on the in-process fakes)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
from pydantic import BaseModel

from drivers.crs_a465 import MotionGuard, SafetyLimits
from sim.station import sim_safety, taught_artifacts_mm, taught_normals, taught_turns_deg
from sim.world import World
from station.kinds import get_plan
from station.kinds.calibration.params import CalibrationCell, CalibrationParams
from station.kinds.calibration.plan import CALIBRATION
from station.kinematics import Kinematics
from station.plans import CaptureResult, MoveJoints, PlanContext, ReferencePose, Step, parse_params
from station.record import Record
from station.runner import SessionRunner, SessionState
from station.testing import FakeRobot, FakeStation
from station.vision import MeasureParams
from tests.sessions.conftest import EventLog, results_of, sid_of

REF = (0.0, 30.0, 60.0, 0.0, 90.0, 0.0)
JOGGED = (20.0, 60.0, 30.0, 140.0, 60.0, -40.0)  # over another artifact, the wrist turned (an abort)
NEAR = (5.0, 25.0, 70.0, -3.0, 90.0, 10.0)  # within one step of the reference (a cycle cut short)


def runner(record: Record, fake: FakeStation, kind: str, **params: Any) -> tuple[SessionRunner, EventLog]:
    plan = get_plan(kind)
    r = SessionRunner(record, plan, parse_params(plan, params), devices=fake.devices())
    log = EventLog()
    r.subscribe(log)
    return r, log


def moves(fake: FakeStation) -> list[tuple[float, ...]]:
    return [c[0] for c in fake.robot.calls_of("move_joints")]


def test_a_repeatability_after_a_jog_starts_with_the_route_through_the_lift_pose(
    record: Record, fake: FakeStation
) -> None:
    r, log = runner(record, fake, "repeatability", cycles=3, warmup_cycles=0, joints=[2], settle_s=0.0)
    fake.robot.joints = np.array(JOGGED)  # the reference is configured; the arm is elsewhere
    assert r.run() is SessionState.SUCCEEDED, r.error
    sid = sid_of(r)
    first = min(record.steps(sid), key=lambda s: s.started_at)
    assert (first.name, first.state) == ("to the reference pose (through the lift pose)", "done")
    sent = moves(fake)
    route = sent[: sent.index(REF) + 1]
    assert (20.0, 0.0, 0.0, 140.0, 60.0, -40.0) in route  # first up: upper arm and forearm upright
    previous = np.array(JOGGED)
    for q in route:  # every step within the driver's 30 deg less the route's margin
        assert np.max(np.abs(np.array(q) - previous)) <= 27.0 + 1e-9
        previous = np.array(q)
    # pre-flight checked the route from where the arm was, and the session measured at the reference
    assert log.of("preflight")[0].data["problems"] == []
    assert all(c.meta["joints_deg"] == list(REF) for c in record.captures(sid))
    assert results_of(record, r)["tests"]["J2"]["n_cycles"] == 3
    # progress counts the plan's steps (the reference, the cycles), not the route before them
    assert r.progress().done == r.progress().total == 1 + 3
    assert log.of("preflight")[0].data["plan_steps"] == 1 + 3
    assert log.of("preflight")[0].data["steps"] == 1 + 1 + 3  # every step checked: the route too


def test_a_short_way_back_is_one_move_and_at_the_reference_there_is_no_route(
    record: Record, fake: FakeStation
) -> None:
    r, _ = runner(record, fake, "repeatability", cycles=2, warmup_cycles=0, joints=[1], settle_s=0.0)
    fake.robot.joints = np.array(NEAR)
    assert r.run() is SessionState.SUCCEEDED, r.error
    assert moves(fake)[0] == REF
    assert [s.name for s in record.steps(sid_of(r))][-1] == "to the reference pose (direct)"
    again, _ = runner(record, fake, "repeatability", cycles=2, warmup_cycles=0, joints=[1], settle_s=0.0)
    assert again.run() is SessionState.SUCCEEDED
    assert not [s for s in record.steps(sid_of(again)) if s.name.startswith("to the reference pose")]


def test_a_route_the_driver_refuses_is_a_preflight_problem_and_nothing_moves(record: Record) -> None:
    # joint 3 may not reach 0 here: the lift pose is out of the arm's limits
    limits = [
        (-175.0, 175.0),
        (-90.0, 110.0),
        (10.0, 110.0),
        (-180.0, 180.0),
        (-180.0, 180.0),
        (-180.0, 180.0),
    ]
    fake = FakeStation(robot=FakeRobot(REF, limits_deg=limits))
    r, log = runner(record, fake, "repeatability", cycles=2, warmup_cycles=0, joints=[1], settle_s=0.0)
    fake.robot.joints = np.array(JOGGED)
    assert r.run() is SessionState.FAILED
    problems = log.of("preflight")[0].data["problems"]
    assert any(p.startswith("to the reference pose (through the lift pose): joint 3") for p in problems)
    fake.robot.assert_not_called("move_joints")
    assert record.get_session(sid_of(r)).state == "failed"


def test_a_validation_with_the_arm_off_its_reference_is_refused_and_moves_nothing(
    record: Record, fake: FakeStation
) -> None:
    r, log = runner(record, fake, "validation", steps_per_side=2)
    fake.robot.joints = np.array(JOGGED)
    assert r.run() is SessionState.FAILED
    (problem,) = log.of("preflight")[0].data["problems"]
    assert problem.startswith("the arm is not at its reference pose (joint 4 commanded at +140.000 deg")
    assert "a validation never moves the arm" in problem
    assert "to-reference" in problem
    fake.robot.assert_not_called("move_joints")
    fake.table.assert_not_called("move_to")
    assert record.captures(sid_of(r)) == []


class _FarParams(BaseModel):
    pass


class _FarPlan:
    """Goes far from the reference in small steps (each within the driver's step), then stays there: a
    stop there must come back through the lift pose (a direct move would break the step limit)."""

    name = "far"
    Params = _FarParams
    needs = frozenset({"robot"})

    def steps(self, params: _FarParams, ctx: PlanContext) -> Iterator[Step]:
        away = [(0.0, 30.0, 60.0, a, 90.0, 0.0) for a in (25.0, 50.0, 75.0, 90.0)]
        yield Step(0, "away", tuple(MoveJoints(q) for q in away), {})
        yield Step(1, "stay", (MoveJoints(away[-1]),), {})

    def resume_prelude(self, params: _FarParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: _FarParams, ctx: PlanContext) -> ReferencePose | None:
        assert ctx.reference_joints_deg is not None
        return ReferencePose(tuple(ctx.reference_joints_deg))

    def analyse(
        self, params: _FarParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        return {}


def test_a_stop_far_from_the_reference_returns_along_the_route(record: Record, fake: FakeStation) -> None:
    r = SessionRunner(record, _FarPlan(), _FarParams(), devices=fake.devices())
    log = EventLog()
    r.subscribe(log)
    fake.robot.listeners.append(lambda q: r.stop() if q[3] == 90.0 else None)
    assert r.run() is SessionState.STOPPED
    (returned,) = log.of("returned")
    route = returned.data["moves"]
    assert [0.0, 0.0, 0.0, 90.0, 90.0, 0.0] in route  # up, turn the wrist back upright, down
    assert route[-1] == list(REF)
    assert tuple(fake.robot.joints) == REF
    assert not log.of("warning")


def test_a_resumed_calibration_travels_from_the_reference_to_where_its_next_configuration_starts() -> None:
    """After the session's route to the reference, the prelude takes the arm to the previous configuration's
    pose, from which the next configuration's own travel starts: the whole chain passes the driver's
    limit, step and keep-out checks."""
    world = World()
    cell = CalibrationCell(
        kinematics=Kinematics(tool=world.kinematics.tool),
        artifacts_mm=tuple(taught_artifacts_mm(world)),
        artifact_turns_deg=tuple(taught_turns_deg(world)),
        artifact_normals=tuple(taught_normals(world)),
        working_distance_mm=68.0,
        focal_px=6800.0,
        sensor_mount=np.eye(4),
        reference_joints_deg=REF,
    )
    ctx = PlanContext(measure_params=MeasureParams(), reference_joints_deg=REF, cell=cell)
    params = CalibrationParams(placements=[1, 2], turns_deg=[-20.0, 70.0], solutions=2)
    steps = list(CALIBRATION.steps(params, ctx))
    configs = CALIBRATION.configurations(params, cell)
    guard = MotionGuard(SafetyLimits(**sim_safety(world)))
    assert CALIBRATION.resume_prelude(params, ctx, steps[0]) == []  # the first travels from the reference
    for k in (1, 2, len(steps) - 1):
        (prelude,) = CALIBRATION.resume_prelude(params, ctx, steps[k])
        to_previous = [a.target_deg for a in prelude.actions if isinstance(a, MoveJoints)]
        assert to_previous[-1] == configs[k - 1].joints_deg
        own = [a.target_deg for a in steps[k].actions if isinstance(a, MoveJoints)]
        here = np.array(REF)
        for q in [*to_previous, *own]:
            guard.plan_single_joint_moves(here, [(i + 1, float(d)) for i, d in enumerate(np.array(q) - here)])
            here = np.array(q)
