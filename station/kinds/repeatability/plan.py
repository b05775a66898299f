"""The seed's repeatability test (section 5, eqs. 13-18, Table 2, Figures 16-17), after ISO 9283.

Per test the arm captures at the reference pose, then ``cycles`` times leaves it and returns and
captures again, after ``warmup_cycles`` uncaptured cycles (ISO 9283 asks for a warm-up). A joint test
moves joint ``j`` by ``delta_deg`` and back; a sequence test visits its list of joint targets and
returns. RP = l-bar + 3 S_l of the positions at the return captures, with a bootstrap 95 % interval for that
number of cycles. The position is the tool point's: where the camera's optical axis meets the artifact,
in the artifact's axes (mm), from one homography fitted over the test's captures. With a distance
sensor, each capture also has z (mm along the sensor's beam) and each test reports RP in 3-D (x, y, z)
as well (``rp3d_mm`` and the other ``*3d*`` keys); the 2-D figures stay as they are.

The sign of each joint's excursion defaults to the one that does not bring the camera toward the
artifact (from the kinematics and the configured camera and artifact plane); pre-flight then checks
every motion with the driver.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.devices import JOINT_COUNT, Joints6
from station.metrology import repeatability, rp_interval
from station.plans import (
    Capture,
    CaptureResult,
    MoveJoints,
    PlanContext,
    PlanError,
    ReferencePose,
    SetSpeed,
    Settle,
    Step,
)
from station.plans._analysis import failures, group_mean, measured, principal_point, series_positions_mm
from station.plans._gates import Check, at_least, at_most, checks_json

FloatArray = npt.NDArray[np.float64]

#: The seed's Table 2: RP (mm) per joint, delta 10 deg, about 80 % speed and 50 % rated load, 30 cycles.
SEED_TABLE2_MM = {"J1": 0.01664, "J2": 0.01813, "J3": 0.02321, "J4": 0.01671, "J5": 0.05299, "J6": 0.01601}


#: A test's reference capture farther than this from the session's first: the arm or the artifact moved.
REFERENCE_LIMIT_MM = 0.5
#: An RP at or above this is no arm's repeatability (the seed's worst joint: 0.053 mm).
RP_LIMIT_MM = 1.0


class RepeatabilityParams(BaseModel):
    """Parameters of a repeatability session."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    cycles: int = Field(30, ge=2, le=100_000)
    warmup_cycles: int = Field(3, ge=0, le=1000)
    joints: list[int] = Field(default_factory=lambda: [1, 2, 3, 4, 5, 6])
    delta_deg: float = Field(10.0, gt=0, le=90)
    signs: list[int] | None = Field(None, description="six values of +1/-1; default: away from the artifact")
    sequences: dict[str, list[Joints6]] = Field(default_factory=dict)
    speed_pct: int = Field(80, ge=1, le=100)
    frames_per_capture: int = Field(1, ge=1, le=100)
    settle_s: float = Field(
        0.25,
        ge=0,
        le=600,
        description="wait after arrival before capturing: the servos settle (seed: ~0.25 s)",
    )
    load_kg: float | None = Field(None, ge=0, le=100, description="recorded only")
    reference_joints_deg: Joints6 | None = None

    @field_validator("joints")
    @classmethod
    def _joints(cls, v: list[int]) -> list[int]:
        if not v and v is not None:
            return v
        bad = [j for j in v if not 1 <= j <= JOINT_COUNT]
        if bad:
            raise ValueError(f"joints must be numbers 1-{JOINT_COUNT}, got {bad}")
        if len(set(v)) != len(v):
            raise ValueError(f"joints repeat: {v}")
        return v

    @field_validator("signs")
    @classmethod
    def _signs(cls, v: list[int] | None) -> list[int] | None:
        if v is not None and (len(v) != JOINT_COUNT or any(s not in (-1, 1) for s in v)):
            raise ValueError(f"signs must be six values, each +1 or -1, got {v}")
        return v

    @field_validator("sequences")
    @classmethod
    def _sequences(cls, v: dict[str, list[Joints6]]) -> dict[str, list[Joints6]]:
        for name, targets in v.items():
            if not name or name.upper() in {f"J{j}" for j in range(1, 7)}:
                raise ValueError(f"sequence name {name!r} is empty or clashes with a joint test's name")
            if not targets:
                raise ValueError(f"sequence {name!r} has no targets")
            if not all(math.isfinite(a) for t in targets for a in t):
                raise ValueError(f"sequence {name!r} has a non-finite angle")
        return v


def test_names(params: RepeatabilityParams) -> list[str]:
    return [f"J{j}" for j in params.joints] + list(params.sequences)


def choose_signs(params: RepeatabilityParams, ctx: PlanContext, reference: Sequence[float]) -> list[int]:
    """Per joint, the sign that does not bring the camera toward the artifact (``+1`` where it makes no
    difference or the geometry is unknown); explicit ``signs`` win."""
    if params.signs is not None:
        return list(params.signs)
    signs = []
    for j in range(JOINT_COUNT):
        if ctx.camera_height_mm is None:
            signs.append(1)
            continue
        plus = list(reference)
        minus = list(reference)
        plus[j] += params.delta_deg
        minus[j] -= params.delta_deg
        h_plus, h_minus = ctx.camera_height_mm(plus), ctx.camera_height_mm(minus)
        signs.append(-1 if h_minus > h_plus + 1e-6 else 1)
    return signs


class RepeatabilityPlan:
    name = "repeatability"
    Params = RepeatabilityParams
    needs = frozenset({"robot", "camera"})

    def table_content(self, params: RepeatabilityParams) -> str:
        """The artifact's cross on the X-Y table: the camera measures its crossing
        (``station.table_content``)."""
        return "cross"

    def _reference(self, params: RepeatabilityParams, ctx: PlanContext) -> tuple[float, ...]:
        ref = params.reference_joints_deg or ctx.reference_joints_deg
        if ref is None:
            raise PlanError(
                "no reference pose: configure robot.reference_joints_deg or pass reference_joints_deg"
            )
        return tuple(float(a) for a in ref)

    def _excursions(
        self, params: RepeatabilityParams, ctx: PlanContext
    ) -> list[tuple[str, list[tuple[float, ...]]]]:
        ref = self._reference(params, ctx)
        signs = choose_signs(params, ctx, ref)
        tests: list[tuple[str, list[tuple[float, ...]]]] = []
        for j in params.joints:
            away = list(ref)
            away[j - 1] += signs[j - 1] * params.delta_deg
            tests.append((f"J{j}", [tuple(away)]))
        for name, targets in params.sequences.items():
            tests.append((name, [tuple(float(a) for a in t) for t in targets]))
        return tests

    def steps(self, params: RepeatabilityParams, ctx: PlanContext) -> Iterator[Step]:
        if not params.joints and not params.sequences:
            raise PlanError("nothing to test: give joints and/or sequences")
        ref = self._reference(params, ctx)
        index = 0
        first = True
        for test, away in self._excursions(params, ctx):
            prefix = (SetSpeed(params.speed_pct),) if first else ()
            first = False
            meta = {"role": "reference", "test": test}
            yield Step(
                index, f"{test} reference", (*prefix, MoveJoints(ref), *self._capture(params, meta)), meta
            )
            index += 1
            for k in range(params.warmup_cycles):
                wmeta = {"role": "warmup", "test": test, "cycle": k}
                yield Step(
                    index, f"{test} warm-up {k + 1}", (*(MoveJoints(a) for a in away), MoveJoints(ref)), wmeta
                )
                index += 1
            for k in range(params.cycles):
                cmeta = {"role": "cycle", "test": test, "cycle": k}
                actions = (*(MoveJoints(a) for a in away), MoveJoints(ref), *self._capture(params, cmeta))
                yield Step(index, f"{test} cycle {k + 1}", actions, cmeta)
                index += 1

    def _capture(self, params: RepeatabilityParams, meta: dict[str, Any]) -> tuple[Any, ...]:
        settle = (Settle(params.settle_s),) if params.settle_s else ()
        return (*settle, Capture(params.frames_per_capture, meta))

    def reference_pose(self, params: RepeatabilityParams, ctx: PlanContext) -> ReferencePose | None:
        """Every test starts and ends at the reference pose: the session's route goes there first."""
        ref = params.reference_joints_deg or ctx.reference_joints_deg
        return None if ref is None else ReferencePose(tuple(float(a) for a in ref))

    def resume_from(
        self, params: RepeatabilityParams, ctx: PlanContext, steps: Sequence[Step], next_step: Step
    ) -> tuple[int, str]:
        """A resume reruns the interrupted test from its start (its reference, warm-up and every cycle):
        one test's cycles are never pooled across an interruption."""
        test = next_step.meta.get("test")
        first = min(s.index for s in steps if s.meta.get("test") == test)
        return first, f"resumed: test {test} runs again from its start (reference, warm-up, every cycle)"

    def resume_prelude(self, params: RepeatabilityParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        """The session's speed again (the test that runs next starts at the reference pose itself)."""
        meta = {"role": "resume", "test": next_step.meta.get("test")}
        return [Step(-1, "resume: speed", (SetSpeed(params.speed_pct),), meta)]

    def analyse(
        self, params: RepeatabilityParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        width = ctx.measure_params.groove_width_mm
        tests: dict[str, Any] = {}
        checks: list[Check] = []
        excursions = dict(self._excursions(params, ctx))
        populations = {test: population(captures, test) for test in test_names(params)}
        first = _first_position(populations)
        for test in test_names(params):
            pop = populations[test]
            mine = [c for c in measured(pop) if c.meta.get("role") in ("reference", "cycle")]
            cycles = [c for c in mine if c.meta.get("role") == "cycle"]
            n = len({c.meta["cycle"] for c in cycles})
            checks += _test_checks(test, n, params.cycles, _position(mine), first)
            common: dict[str, Any] = {
                "n_cycles": n,
                "planned_cycles": params.cycles,
                "partial": n < params.cycles,
                "failures": failures([c for c in pop if c.meta.get("role") in ("reference", "cycle")]),
            }
            left = excluded(captures, test, pop)
            if left:
                common["excluded_captures"] = left
            if n < 3:
                tests[test] = {
                    "error": f"only {n} cycle captures were measured; RP needs at least 3",
                    **common,
                }
                continue
            # The tool point: where the optical axis meets the artifact, relative to the crossing (RP is
            # a position repeatability; a turn about the optical axis does not move this point).
            pp = principal_point(mine, ctx.measure_params.camera_matrix)
            pos = series_positions_mm(mine, width, relative_to_px=pp)
            is_cycle = [c.meta.get("role") == "cycle" for c in mine]
            keys, points = group_mean([c.meta["cycle"] for c in cycles], pos[np.array(is_cycle)])
            rep = repeatability(points)
            lo, hi = rp_interval(points)
            checks.append(rp_check(test, rep.rp))
            entry: dict[str, Any] = {
                "kind": "sequence" if test in params.sequences else "joint",
                "points_mm": points.tolist(),
                "cycles": [int(k) for k in keys],
                "barycentre_mm": list(rep.barycentre),
                "l_bar_mm": rep.l_bar,
                "s_l_mm": rep.s_l,
                "rp_mm": rep.rp,
                "rp_ci95_mm": [lo, hi],
                **common,
            }
            entry.update(_rp3d(cycles, pos[np.array(is_cycle)]))
            if test in params.sequences:
                entry["targets_deg"] = [list(t) for t in params.sequences[test]]
            else:
                joint = int(test[1:])
                away = list(excursions[test][0])
                ref = self._reference(params, ctx)
                entry["joint"] = joint
                entry["delta_deg"] = away[joint - 1] - ref[joint - 1]  # signed: the direction used
                entry["away_deg"] = away
            tests[test] = entry
        out: dict[str, Any] = {
            # the headline holds whole tests only: a partial test's RP is in its own entry
            "rp_mm": {t: e["rp_mm"] for t, e in tests.items() if "rp_mm" in e and not e["partial"]},
            "n_cycles": params.cycles,
            "tests": tests,
            "speed_pct": params.speed_pct,
            "load_kg": params.load_kg,
            "seed_table2_mm": SEED_TABLE2_MM,
            "partial": any(e["partial"] for e in tests.values()),
            "checks": checks_json(checks),
        }
        rp3d = {t: e["rp3d_mm"] for t, e in tests.items() if "rp3d_mm" in e and not e["partial"]}
        if rp3d:
            out["rp3d_mm"] = rp3d
        return out


def _run(c: CaptureResult) -> int:
    return int(c.meta.get("run", 0))


def population(captures: Sequence[CaptureResult], test: str) -> list[CaptureResult]:
    """The captures of ``test``'s latest run: a resume reruns a test from its start, so its latest run
    holds its reference and cycles; captures of earlier runs are never pooled with them."""
    mine = [c for c in captures if c.meta.get("test") == test]
    if not mine:
        return []
    latest = max(_run(c) for c in mine)
    return [c for c in mine if _run(c) == latest]


def excluded(captures: Sequence[CaptureResult], test: str, pop: Sequence[CaptureResult]) -> list[int]:
    """Capture ids of ``test`` left out because they belong to an earlier run than its population."""
    used = {c.capture_id for c in pop}
    return [c.capture_id for c in captures if c.meta.get("test") == test and c.capture_id not in used]


def _position(captures: Sequence[CaptureResult]) -> tuple[float, float] | None:
    """Where a test saw the crossing first (mm, the measurement's ``center_mm``): its reference capture,
    else its first measured cycle."""
    for c in captures:
        m = c.measurement
        if m is not None and m.get("center_mm") is not None:
            x, y = m["center_mm"]
            return float(x), float(y)
    return None


def _first_position(populations: dict[str, list[CaptureResult]]) -> tuple[float, float] | None:
    """The session's first reference position: the earliest step's measured reference-or-cycle capture."""
    caps = [
        c
        for pop in populations.values()
        for c in measured(pop)
        if c.meta.get("role") in ("reference", "cycle")
    ]
    caps.sort(key=lambda c: (c.step_index, c.frame_index))
    return _position(caps)


def _test_checks(
    test: str,
    n: int,
    planned: int,
    here: tuple[float, float] | None,
    first: tuple[float, float] | None,
) -> list[Check]:
    out = [
        at_least(
            f"cycles:{test}",
            n,
            planned,
            severity="warn",
            ok=f"{test}: all {{value}} planned cycles measured",
            bad=f"{test} is partial: {{value}} of {{limit}} cycles measured; its RP is its own, not in rp_mm",
        )
    ]
    offset = None
    if here is not None and first is not None:
        offset = math.hypot(here[0] - first[0], here[1] - first[1])
    out.append(
        at_most(
            f"reference:{test}",
            offset,
            REFERENCE_LIMIT_MM,
            severity="fail",
            ok=f"{test}: the reference capture is {{value}} mm from the session's first",
            bad=f"{test}: the reference capture is {{value}} mm from the session's first "
            "(limit {limit} mm): the arm or the artifact moved; check the artifact's mounting and the "
            "reference pose, then start a new session",
        )
    )
    return out


def rp_check(test: str, rp_mm: float) -> Check:
    return at_most(
        f"rp:{test}",
        rp_mm,
        RP_LIMIT_MM,
        severity="fail",
        ok=f"{test}: RP {{value}} mm is physically possible (below {{limit}} mm)",
        bad=f"{test}: RP {{value}} mm is not an arm's repeatability (limit {{limit}} mm): the camera lost "
        "the artifact or it moved during the test; check the artifact and the captures, then start again",
    )


def _rp3d(cycles: Sequence[CaptureResult], xy_mm: FloatArray) -> dict[str, Any]:
    """ISO 9283 RP in 3-D from the cycle captures' (x, y) and the distance sensor's z (mm), when every
    cycle capture has a z; nothing when none has (a station without a sensor); an explanation when only
    some have."""
    z = [c.z_mm for c in cycles]
    if all(v is None for v in z):
        return {}
    missing = [c.capture_id for c in cycles if c.z_mm is None]
    if missing:
        why = sorted({str(c.meta.get("z_error", "no reading")) for c in cycles if c.z_mm is None})
        return {"rp3d_error": f"no z on {len(missing)} of {len(cycles)} cycle captures: {'; '.join(why)}"}
    xyz = np.column_stack([xy_mm, np.array(z, dtype=np.float64)])
    _, points = group_mean([c.meta["cycle"] for c in cycles], xyz)
    rep = repeatability(points)
    lo, hi = rp_interval(points)
    return {
        "points3d_mm": points.tolist(),
        "barycentre3d_mm": list(rep.barycentre),
        "l_bar3d_mm": rep.l_bar,
        "s_l3d_mm": rep.s_l,
        "rp3d_mm": rep.rp,
        "rp3d_ci95_mm": [lo, hi],
    }


REPEATABILITY = RepeatabilityPlan()
