"""The ``sweep`` kind's plan: a stored validation session re-measured over a parameter grid (default: the
seed's Table 1 trials) with the ``station sweep`` core, one step per trial."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.displacements import CALIBRATIONS
from station.imagesets import ImageSet
from station.parameter_study import grid, run_sweep, seed_trials
from station.plans import CaptureResult, Compute, PlanContext, PlanError, ReferencePose, Step
from station.plans._recorded import record_of
from station.vision import field_name


class SweepParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    session: str = Field(min_length=4, description="id (or unique prefix) of a stored validation session")
    grid: dict[str, list[Any]] | None = Field(
        None,
        description="parameter grid (names case-insensitive, as --set's); default: the seed's Table 1",
    )
    calibration: Literal["image", "series"] = Field("image", description="as station sweep's --calibration")

    @field_validator("grid")
    @classmethod
    def _grid_names(cls, v: dict[str, list[Any]] | None) -> dict[str, list[Any]] | None:
        """The measurement parameters' own names (``TESTWIDTH`` -> ``testwidth``), each at most once and
        with at least one value: an unknown name is refused here, not when the trials run."""
        if v is None:
            return None
        out: dict[str, list[Any]] = {}
        for name, values in v.items():
            key = field_name(name, option="grid")
            if key in out:
                raise ValueError(f"grid {name!r}: {key} is already in the grid (names are case-insensitive)")
            if not values:
                raise ValueError(f"grid {name!r}: no values; give at least one, e.g. {{{key!r}: [3, 5]}}")
            out[key] = values
        return out


class SweepPlan:
    name = "sweep"
    Params = SweepParams
    needs: frozenset[str] = frozenset()

    def source_session(self, params: SweepParams) -> str:
        return params.session

    def image_set(self, params: SweepParams, ctx: PlanContext) -> ImageSet:
        record = record_of(ctx)
        source = record.get_session(params.session)
        if source.kind != "validation":
            raise PlanError(
                f"session {source.id} is a {source.kind} session; a sweep needs a validation session"
            )
        caps = [c for c in record.captures(source.id) if c.meta.get("role") == "position"]
        if len(caps) < 3:
            raise PlanError(
                f"session {source.id} has {len(caps)} position captures; a sweep needs at least 3"
            )
        files = tuple(Path(record.data_dir) / c.path for c in caps)
        disp = np.array([c.meta["commanded_um"] for c in caps], dtype=np.float64)
        return ImageSet(Path(record.data_dir), files, disp, {}, {"session": source.id})

    def overrides(self, params: SweepParams) -> list[dict[str, Any]]:
        return grid(params.grid) if params.grid is not None else seed_trials()

    def steps(self, params: SweepParams, ctx: PlanContext) -> Iterator[Step]:
        if params.calibration not in CALIBRATIONS:
            raise PlanError(f"calibration must be one of {CALIBRATIONS}")
        for number, change in enumerate(self.overrides(params), start=1):

            def run(c: PlanContext, change: dict[str, Any] = change, number: int = number) -> dict[str, Any]:
                image_set = self.image_set(params, c)
                trial = run_sweep(
                    image_set,
                    c.measure_params,
                    [change],
                    jobs=c.jobs,
                    backend=c.compute,
                    calibration=params.calibration,
                )[0]
                trial_doc: dict[str, Any] = {"number": number, "overrides": change, "error": trial.error}
                if trial.result is not None:
                    comp = trial.result.comparison
                    trial_doc.update(
                        mean_um=comp.rigid.mean,
                        max_um=comp.rigid.max,
                        parallelogram_mean_um=comp.affine.mean,
                        parallelogram_max_um=comp.affine.max,
                    )
                else:
                    trial_doc.update(
                        mean_um=None, max_um=None, parallelogram_mean_um=None, parallelogram_max_um=None
                    )
                return trial_doc

            yield Step(number - 1, f"trial {number}", (Compute(run, f"trial {number}"),), {"trial": number})

    def resume_prelude(self, params: SweepParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: SweepParams, ctx: PlanContext) -> ReferencePose | None:
        return None  # no device

    def analyse(
        self, params: SweepParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        record = record_of(ctx)
        assert ctx.session_id is not None
        trials = [s.data for s in record.steps(ctx.session_id) if s.state == "done" and "number" in s.data]
        trials.sort(key=lambda t: t["number"])
        # the seed's Table 1 ranks by MeanE then MaxE after the well-fit parallelogram (station sweep too)
        ok = [t for t in trials if t.get("parallelogram_mean_um") is not None]
        key = lambda t: (round(t["parallelogram_mean_um"], 4), t["parallelogram_max_um"])  # noqa: E731
        best = min(ok, key=key)["number"] if ok else None
        return {"trials": trials, "best": best, "source_session": record.get_session(params.session).id}


SWEEP = SweepPlan()
