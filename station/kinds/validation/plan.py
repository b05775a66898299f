"""The seed's validation (section 4, Figures 13-15): the artifact moved through a known pattern on the
manual micrometer X-Y table, one operator prompt per position, each position's image measured, and the
measured displacements compared with the commanded ones after rigid, similarity and affine fits.

Every position is approached from the same direction by default (``approach = "same-direction"``): a
position reached by turning a micrometer backwards is first overshot by ``approach_um`` and then
reached forwards, which takes the micrometers' backlash out, as metrologists do. ``"direct"`` is the
seed's plain path. The similarity fit's scale estimates the artifact's true groove width (known only to
+0/-0.002 in): ``groove_width_mm / scale``, with its standard uncertainty, stored as the station's scale
calibration.

With ``artifact = "ruler"`` the table carries a ruler (``station/vision/RULER.md``) instead of the
crossed artifact: each frame is measured with ``measure_ruler`` (the absolute position along the ruler
and the offset across it of the point under the reference pixel), the same fits and gates follow; the
similarity's scale then compares the micrometers with the ruler's certified pitch, there is no groove
width to estimate and no scale calibration is written.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.kinds.validation.gates import (
    GROOVE_BAND_MM,
    RIGID_LIMITS_UM,
    groove_check,
    live_resume,
    live_table_moves,
    positions_check,
    resume_check,
    rigid_checks,
    table_moves_check,
    table_point_mm,
)
from station.metrology import fit_affine, fit_rigid, scale_uncertainty
from station.patterns import STEP_UM, STEPS_PER_SIDE, validation_pattern_um
from station.plans import (
    Capture,
    CaptureResult,
    MoveTable,
    PlanContext,
    PlanError,
    ReferencePose,
    Settle,
    Step,
)
from station.plans._analysis import failures, group_mean, measured, series_positions_mm
from station.plans._gates import checks_json
from station.plans._ruler import ARTIFACT_KEY, RULER


class ValidationParams(BaseModel):
    """Parameters of a validation session (um where the seed reports um)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    pattern_um: list[tuple[float, float]] | None = Field(
        None, description="table positions (um, table axes); default: the seed's 40-position square"
    )
    step_um: float = Field(STEP_UM, gt=0, le=10_000, description="the default square's step")
    steps_per_side: int = Field(
        STEPS_PER_SIDE, ge=1, le=1000, description="the default square's steps a side"
    )
    origin_mm: tuple[float, float] = Field((0.0, 0.0), description="table position of the pattern's (0, 0)")
    artifact: Literal["cross", "ruler"] = Field(
        "cross", description="what the table carries: the crossed-groove artifact or a ruler"
    )
    frames_per_position: int = Field(1, ge=1, le=100)
    approach: Literal["same-direction", "direct"] = "same-direction"
    approach_um: float = Field(25.4, gt=0, le=1000, description="overshoot before a backwards approach")
    settle_s: float = Field(0.0, ge=0, le=600)
    prompt_timeout_s: float | None = Field(None, gt=0, description="operator answer timeout (None: wait)")
    mean_limit_um: float | None = Field(
        None, gt=0, le=10_000, description="rigid fit's mean error limit (um); default 2 precise, 20 paper"
    )
    max_limit_um: float | None = Field(
        None, gt=0, le=10_000, description="rigid fit's max error limit (um); default 6 precise, 50 paper"
    )
    groove_width_band_mm: tuple[float, float] = Field(
        GROOVE_BAND_MM,
        description="the artifact's groove width tolerance band (mm); default 1/32 in +0/-0.002 in",
    )

    @field_validator("groove_width_band_mm")
    @classmethod
    def _band(cls, v: tuple[float, float]) -> tuple[float, float]:
        lo, hi = v
        if not (math.isfinite(lo) and math.isfinite(hi) and 0.05 <= lo <= hi <= 50.0):
            raise ValueError(f"the band must be [low, high] mm with 0.05 <= low <= high <= 50, got {list(v)}")
        return v

    @field_validator("pattern_um")
    @classmethod
    def _pattern(cls, v: list[tuple[float, float]] | None) -> list[tuple[float, float]] | None:
        if v is None:
            return v
        if len(v) < 3:
            raise ValueError(f"a pattern needs at least 3 positions, got {len(v)}")
        if not all(math.isfinite(a) and math.isfinite(b) for a, b in v):
            raise ValueError("pattern positions must be finite numbers (um)")
        return v

    def positions_um(self) -> list[tuple[float, float]]:
        if self.pattern_um is not None:
            return [(float(x), float(y)) for x, y in self.pattern_um]
        return validation_pattern_um(self.step_um, self.steps_per_side)


class ValidationPlan:
    name = "validation"
    Params = ValidationParams
    needs = frozenset({"camera", "table"})
    #: the session that measures the artifact's width: the pre-flight scale check only warns
    #: (``station.scale_preflight``), its groove-width gate judges the width
    scale_check = "warn"

    def steps(self, params: ValidationParams, ctx: PlanContext) -> Iterator[Step]:
        ox, oy = params.origin_mm
        last: tuple[float, float] | None = None
        for i, (x_um, y_um) in enumerate(params.positions_um()):
            x, y = ox + x_um / 1000.0, oy + y_um / 1000.0
            actions: list[Any] = []
            if params.approach == "same-direction" and (last is None or x < last[0] or y < last[1]):
                a = params.approach_um / 1000.0
                actions.append(MoveTable(x - a, y - a, overshoot=True))
            actions.append(MoveTable(x, y))
            if params.settle_s:
                actions.append(Settle(params.settle_s))
            meta: dict[str, Any] = {
                "role": "position",
                "position": i,
                "commanded_um": [x_um, y_um],
                "table_mm": [x, y],
            }
            if params.artifact == RULER:
                meta[ARTIFACT_KEY] = RULER
            actions.append(Capture(params.frames_per_position, meta))
            yield Step(i, f"position {i}", tuple(actions), meta)
            last = (x, y)

    def table_content(self, params: ValidationParams) -> str:
        """What must lie on the X-Y table (``station.table_content``): a ruler for a validation made with
        one, else the artifact's cross."""
        return "ruler" if params.artifact == RULER else "cross"

    def reference_pose(self, params: ValidationParams, ctx: PlanContext) -> ReferencePose | None:
        """The arm at the station's reference pose, over the table's artifact; never moved by a validation
        (the operator's hands are at the micrometers under it): pre-flight refuses it anywhere else."""
        ref = ctx.reference_joints_deg
        return None if ref is None else ReferencePose(tuple(float(a) for a in ref), route=False)

    def resume_prelude(self, params: ValidationParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        """The last confirmed position captured again (approached from below, backlash taken out): the
        session continues only if it measures where it did before the interruption (``check_progress``).
        """
        if next_step.index == 0:
            return []
        last = list(self.steps(params, ctx))[next_step.index - 1]
        x, y = last.meta["table_mm"]
        a = params.approach_um / 1000.0
        actions: list[Any] = [MoveTable(x - a, y - a, overshoot=True), MoveTable(x, y)]
        if params.settle_s:
            actions.append(Settle(params.settle_s))
        meta = {**last.meta, "role": "resume_check"}
        actions.append(Capture(params.frames_per_position, meta))
        return [Step(-1, f"resume: {last.name} again", tuple(actions), meta)]

    def check_progress(
        self, params: ValidationParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> None:
        """Live gates: a resume's re-capture must match, and the image must follow the table."""
        live_resume(captures)
        live_table_moves(captures)

    def analyse(
        self, params: ValidationParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        ok = [c for c in measured(captures) if c.meta.get("role") == "position"]
        width = ctx.measure_params.groove_width_mm
        ruler = params.artifact == RULER
        if len({c.meta["position"] for c in ok}) < 3:
            message = (
                f"only {len({c.meta['position'] for c in ok})} positions were measured; at least 3 are needed"
            )
            why = failures([c for c in captures if c.meta.get("role") == "position"])
            if ruler and why:  # say what the measurement saw, and what to do
                message += (
                    f" (a frame: {why[0]['error']}); put the ruler on the table under the camera at its "
                    "reference pose, or validate with artifact=cross"
                )
            raise PlanError(message)
        if ruler:  # absolute, from each frame alone: no homography across the series, no groove width
            pos_mm = np.array([table_point_mm(c.measurement or {}) for c in ok], dtype=np.float64)
        else:
            pos_mm = series_positions_mm(ok, width)
        keys, mean_mm = group_mean([c.meta["position"] for c in ok], pos_mm)
        commanded = np.array(
            [next(c.meta["commanded_um"] for c in ok if c.meta["position"] == k) for k in keys]
        )
        commanded = commanded - commanded[0]
        measured_um = (mean_mm - mean_mm[0]) * 1000.0
        rigid = fit_rigid(commanded, measured_um)
        similarity = fit_rigid(commanded, measured_um, with_scale=True)
        # a pattern cut short along one side (a session stopped early) has no parallelogram fit
        affine = fit_affine(commanded, measured_um) if np.linalg.matrix_rank(commanded) >= 2 else None
        rigid_res = measured_um - (commanded @ rigid.A.T + rigid.t)
        affine_res = None if affine is None else measured_um - (commanded @ affine.A.T + affine.t)
        scale = similarity.scale
        u_scale = scale_uncertainty(commanded, similarity)
        seen = scale > 1e-9 and math.isfinite(scale)  # a table whose moves the image does not show: none
        width_est = width / scale if seen else math.nan
        results: dict[str, Any] = {
            "mean_um": rigid.mean,
            "max_um": rigid.max,
            "parallelogram_mean_um": None if affine is None else affine.mean,
            "parallelogram_max_um": None if affine is None else affine.max,
            "scale": scale,
            "groove_width_mm": None if ruler else width_est,
            "groove_width_u_mm": None if ruler else (width * u_scale / scale**2 if seen else math.nan),
            "groove_width_used_mm": None if ruler else width,
            "rigid": rigid.summary_um(),
            "similarity": similarity.summary_um(),
            "affine": None if affine is None else affine.summary_um(),
            "positions": [
                {
                    "index": int(k),
                    "commanded_um": [float(v) for v in commanded[j]],
                    "measured_um": [float(v) for v in measured_um[j]],
                    "error_um": [float(v) for v in rigid_res[j]],
                    "error_parallelogram_um": None
                    if affine_res is None
                    else [float(v) for v in affine_res[j]],
                }
                for j, k in enumerate(keys)
            ],
            "approach": params.approach,
            "n_positions": len(keys),
            "partial": len(keys) < len(params.positions_um()),
            "failures": failures([c for c in captures if c.meta.get("role") == "position"]),
            "scale_calibration": None,
        }
        mode = ctx.measure_params.mode
        default_mean, default_max = RIGID_LIMITS_UM[mode]
        limits = (params.mean_limit_um or default_mean, params.max_limit_um or default_max)
        gates = [
            table_moves_check(commanded, measured_um, keys),
            None
            if ruler
            else groove_check(width_est, results["groove_width_u_mm"], params.groove_width_band_mm),
            *rigid_checks(rigid.mean, rigid.max, limits, mode),
            positions_check(len(keys), len(params.positions_um())),
            resume_check(captures),
        ]
        results["checks"] = checks_json([g for g in gates if g is not None])
        if ruler:
            results["artifact"] = RULER
            results["scale_u"] = u_scale
        elif params.approach == "same-direction" and ctx.session_id is not None and seen:
            results["scale_calibration"] = {
                "groove_width_mm": width_est,
                "u_mm": results["groove_width_u_mm"],
                "session_id": ctx.session_id,
            }
        return results


VALIDATION = ValidationPlan()
