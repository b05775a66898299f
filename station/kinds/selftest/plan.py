"""The controller self-test as a session (issue 23, item 3): ``station.selftest``'s checks (each joint's
direction against the camera's view, WORLD against the station's arm model, the ready pose, the halt key
at low speed) run on the station's devices, recorded with the robot's identity as the session's.

The session starts at the reference pose (the camera over the table's crossing, which the directions
check measures) and runs one step: the self-test drives the arm itself, every motion checked by the robot
(limits, keep-out along the path, the speed cap) at its low speed. The halt check leaves the stop latched
on purpose: a person acknowledges it at the station before the arm moves again.

Gates: each controller check that ``failed`` fails the session; one ``inconclusive`` or ``not_run`` is a
warning (its summary says what to do). The session's latest result is attached to every later session
(``station.selftest_status``) until the controller's identity changes.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.plans import (
    CaptureResult,
    DeviceCheck,
    PlanContext,
    PlanError,
    ReferencePose,
    SetSpeed,
    Step,
)
from station.plans._gates import Check, checks_json
from station.selftest import HALT_SPEED_PCT, run_selftest, selftest_rig

CheckName = Literal["directions", "world", "ready", "halt"]
ALL_CHECKS: tuple[CheckName, ...] = ("directions", "world", "ready", "halt")


class SelftestParams(BaseModel):
    """Parameters of a self-test session."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    checks: list[CheckName] = Field(
        default_factory=lambda: list(ALL_CHECKS),
        description="the checks to run (in the self-test's order): directions, world, ready, halt",
    )

    @field_validator("checks")
    @classmethod
    def _some(cls, v: list[str]) -> list[str]:
        if not v:
            raise ValueError("name at least one check: directions, world, ready, halt")
        if len(set(v)) != len(v):
            raise ValueError(f"each check once, got {v}")
        return v


def _procedure(checks: Sequence[str]) -> Callable[[Any], dict[str, Any]]:
    """The step's device procedure: the rig of the station's configuration and devices, then the checks."""

    def run(devices: Any) -> dict[str, Any]:
        if devices.robot is None:
            raise PlanError("the self-test needs the robot ([robot] in the configuration)")
        # the driver's own limits where it has them (the ready pose, the largest step), as the CLI does
        limits = getattr(getattr(devices.robot, "guard", None), "limits", None)
        rig = selftest_rig(
            devices.config,
            devices.robot,
            devices.camera,
            ready_pose_deg=getattr(limits, "ready_pose_deg", None),
            max_step_deg=getattr(limits, "max_step_deg", None),
        )
        return {"selftest": run_selftest(rig, checks=tuple(checks)).to_dict()}

    return run


def _gate(check: Mapping[str, Any]) -> Check:
    """A controller check as the session's gate: failed fails, inconclusive or not run warns."""
    state = str(check.get("state"))
    name = str(check.get("name"))
    return Check(
        f"selftest_{name}",
        state == "passed",
        None,
        0.0,
        "warn" if state in ("inconclusive", "not_run") else "fail",
        f"{name}: {check.get('summary', '')}",
    )


class SelftestPlan:
    name = "selftest"
    Params = SelftestParams
    needs = frozenset({"robot", "camera"})

    def table_content(self, params: SelftestParams) -> str:
        """The artifact's cross on the X-Y table: the directions check measures its crossing
        (``station.table_content``)."""
        return "cross"

    def steps(self, params: SelftestParams, ctx: PlanContext) -> Iterator[Step]:
        # the speed set first makes pre-flight check the arm (power, homing, the stop latch, the cap)
        actions = (SetSpeed(int(HALT_SPEED_PCT)), DeviceCheck(_procedure(params.checks), "self-test"))
        yield Step(0, "self-test", actions, {"role": "selftest", "checks": list(params.checks)})

    def reference_pose(self, params: SelftestParams, ctx: PlanContext) -> ReferencePose | None:
        """The reference pose: the camera over the table's crossing, which the directions check measures."""
        ref = ctx.reference_joints_deg
        return None if ref is None else ReferencePose(tuple(float(a) for a in ref))

    def resume_prelude(self, params: SelftestParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def analyse(
        self, params: SelftestParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        if ctx.record is None or ctx.session_id is None:
            raise PlanError("a self-test is analysed from its record")
        found = [
            s.data["selftest"]
            for s in ctx.record.steps(ctx.session_id)
            if isinstance(s.data.get("selftest"), Mapping)
        ]
        if not found:
            raise PlanError(
                "the self-test did not finish (its step failed or was interrupted): start it again"
            )
        result = found[-1]
        gates = [_gate(c) for c in result.get("checks", [])]
        if result.get("latched"):
            gates.append(
                Check(
                    "stop_latched",
                    False,
                    None,
                    0.0,
                    "warn",
                    "the halt check latched the stop on purpose: look at the arm, then acknowledge the stop "
                    "at the station (station robot --config F acknowledge) before the arm moves again",
                )
            )
        return {
            "passed": bool(result.get("passed")),
            "identity": dict(result.get("identity") or {}),
            "latched": bool(result.get("latched")),
            "start_joints_deg": list(result.get("start_joints_deg") or []),
            "started_at": result.get("started_at"),
            "finished_at": result.get("finished_at"),
            "controller_checks": list(result.get("checks", [])),
            "checks": checks_json(gates),
        }


SELFTEST = SelftestPlan()
