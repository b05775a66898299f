"""A session in the record (created), its steps (the plan's; on a resume those left, from where the plan's
resume rule says, after its prelude), and the plan's context for a live session."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from pydantic import BaseModel

from station.compute import MeasureBackend
from station.config import StationDevices
from station.kinds import get_plan
from station.plans import Plan, PlanContext, Step, station_cell
from station.record import Record, SessionRow
from station.runner._journal import Journal
from station.runner._states import PRELUDE_BASE, software_info
from station.vision import MeasureParams


@dataclass(frozen=True)
class SessionSteps:
    """What a run of a session does: ``steps`` (the plan's left to run), the ``prelude`` before them (a
    resume's set-up), ``planned`` (the plan's step count over the whole session, which progress counts)
    and ``run`` (0 for a session's first run, n for its n-th resume)."""

    steps: list[Step]
    prelude: list[Step]
    planned: int
    run: int


def session_steps(
    plan: Plan, params: BaseModel, ctx: PlanContext, record: Record, journal: Journal, *, resumed: bool
) -> SessionSteps:
    """The plan's steps, or, for a resumed session, those left (``resumed`` event)."""
    steps = list(plan.steps(params, ctx))
    planned = len(steps)
    prelude: list[Step] = []
    if not resumed:
        return SessionSteps(steps, prelude, planned, 0)
    assert ctx.session_id is not None
    rows = record.steps(ctx.session_id)
    run = 1 + max((int(r.data.get("run", 0)) for r in rows), default=0)
    done = {s.index for s in rows if s.state == "done"}
    remaining = [s for s in steps if s.index not in done]
    n_pre = sum(1 for s in rows if s.index >= PRELUDE_BASE)
    if remaining and done:
        remaining = _redo(plan, params, ctx, record, journal, steps, remaining, done)
        for k, s in enumerate(plan.resume_prelude(params, ctx, remaining[0])):
            prelude.append(Step(PRELUDE_BASE + n_pre + k, s.name, s.actions, s.meta))
    journal.emit(
        "resumed", {"skipped_steps": len(steps) - len(remaining), "remaining": len(remaining), "run": run}
    )
    return SessionSteps(remaining, prelude, planned, run)


def _redo(
    plan: Plan,
    params: BaseModel,
    ctx: PlanContext,
    record: Record,
    journal: Journal,
    steps: list[Step],
    remaining: list[Step],
    done: set[int],
) -> list[Step]:
    """The plan's resume rule (``resume_from``): a resume reruns from that step on, done or not, so
    that no population mixes two runs. The rerun steps' earlier captures stay in the record, marked
    by an ``abandoned`` event, and the analysis takes the new attempt's."""
    rule = getattr(plan, "resume_from", None)
    if rule is None:
        return remaining
    assert ctx.session_id is not None
    first, reason = rule(params, ctx, steps, remaining[0])
    redo = {s.index for s in steps if s.index >= first}
    ids = [c.id for c in record.captures(ctx.session_id) if c.step_index in redo]
    if ids or redo & done:
        # every capture of the steps run again, the interrupted one's included: never analysed again
        journal.emit("abandoned", {"reason": reason, "steps": sorted(redo & done), "captures": ids})
    return [s for s in steps if s.index not in done or s.index >= first]


def create_session(
    record: Record,
    plan: Plan,
    params: BaseModel,
    *,
    devices: StationDevices | None,
    measure_params: MeasureParams,
    scale_calibration: dict[str, Any] | None,
    config_snapshot: dict[str, Any] | None,
    station: str,
) -> SessionRow:
    """A new session in the record (``idle``): its parameters, the station's configuration, the devices'
    identities and the software."""
    snapshot = config_snapshot
    if snapshot is None and devices is not None:
        snapshot = devices.config.snapshot()
    return record.create_session(
        plan.name,
        params={
            "plan": params.model_dump(mode="json"),
            "measure": measure_params.model_dump(mode="json"),
            "scale_calibration": scale_calibration,
        },
        config=snapshot or {},
        identities=devices.identities() if devices is not None else {},
        software=software_info(),
        station=station,
    )


def plan_context(
    plan: Plan,
    sid: str,
    *,
    record: Record,
    devices: StationDevices | None,
    measure_params: MeasureParams,
    jobs: int,
    compute: MeasureBackend | None,
    cancelled: Callable[[], bool],
) -> PlanContext:
    """What the plan sees of the live session: the station's cell, reference pose and camera height."""
    reference = devices.reference_joints_deg if devices is not None else None
    config = devices.config.model_dump(mode="json") if devices is not None else None
    return PlanContext(
        measure_params=measure_params,
        reference_joints_deg=reference,
        camera_height_mm=camera_height_function(devices),
        record=record,
        session_id=sid,
        jobs=jobs,
        cell=station_cell(plan, config, measure_params),
        plan_of=get_plan,
        compute=compute,
        cancelled=cancelled,
    )


def camera_height_function(devices: StationDevices | None) -> Callable[[Sequence[float]], float] | None:
    """Height of the camera's front above the artifact plane for given joints, from the robot's safety
    settings (``table_z_mm``, ``camera_offset_mm``) and the nominal kinematics; ``None`` when unknown."""
    if devices is None or devices.config.robot is None:
        return None
    from station.plans._recorded import camera_height_function as from_safety

    return from_safety(devices.config.robot.safety)
