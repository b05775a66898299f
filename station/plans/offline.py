"""Plans that need no hardware: a stored session measured again.

* ``sweep``: a stored validation session re-measured over a parameter grid (default: the seed's Table 1
  trials) with the ``station sweep`` core, one step per trial.
* ``reanalyse``: any stored session measured again with other parameters or software, on the
  session's compute backend (``station.compute``: the local pool by default, or a Dask cluster), then
  analysed as its own kind. With the same parameters and software it reproduces the stored results
  bit for bit, on any backend.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from station.compute import LocalBackend
from station.imagesets import ImageSet
from station.plans import CaptureResult, Compute, PlanContext, PlanError, ReferencePose, Step
from station.plans._recorded import camera_height_of, reference_of
from station.sweep import grid, run_sweep, seed_trials
from station.validation import CALIBRATIONS
from station.vision import MeasureParams, field_name

CHUNK = 64  # captures per reanalysis step: the runner's pause/stop granularity


def _record(ctx: PlanContext) -> Any:
    if ctx.record is None:
        raise PlanError("this plan reads a stored session: it needs the record")
    return ctx.record


def measure_stored(paths: Sequence[Path], params: MeasureParams, ctx: PlanContext) -> list[dict[str, Any]]:
    """Measure stored image files on the session's backend (else a local pool of ``ctx.jobs``);
    ``station measure --json`` objects, in order."""
    if ctx.compute is not None:
        return [r.to_json() for r in ctx.compute.measure(paths, params, cancelled=ctx.cancelled)]
    with contextlib.closing(LocalBackend(ctx.jobs)) as local:
        return [r.to_json() for r in local.measure(paths, params, cancelled=ctx.cancelled)]


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
        record = _record(ctx)
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
        record = _record(ctx)
        assert ctx.session_id is not None
        trials = [s.data for s in record.steps(ctx.session_id) if s.state == "done" and "number" in s.data]
        trials.sort(key=lambda t: t["number"])
        # the seed's Table 1 ranks by MeanE then MaxE after the well-fit parallelogram (station sweep too)
        ok = [t for t in trials if t.get("parallelogram_mean_um") is not None]
        key = lambda t: (round(t["parallelogram_mean_um"], 4), t["parallelogram_max_um"])  # noqa: E731
        best = min(ok, key=key)["number"] if ok else None
        return {"trials": trials, "best": best, "source_session": record.get_session(params.session).id}


class ReanalyseParams(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    session: str = Field(min_length=4, description="id (or unique prefix) of any stored session")


class ReanalysePlan:
    name = "reanalyse"
    Params = ReanalyseParams
    needs: frozenset[str] = frozenset()

    def source_session(self, params: ReanalyseParams) -> str:
        return params.session

    def steps(self, params: ReanalyseParams, ctx: PlanContext) -> Iterator[Step]:
        record = _record(ctx)
        source = record.get_session(params.session)
        caps = record.captures(source.id)
        if not caps:
            raise PlanError(f"session {source.id} has no captures to measure again")
        for k in range(0, len(caps), CHUNK):
            ids = [c.id for c in caps[k : k + CHUNK]]

            def run(c: PlanContext, ids: list[int] = ids, src: str = source.id) -> dict[str, Any]:
                rec = _record(c)
                assert c.session_id is not None
                by_id = {cap.id: cap for cap in rec.captures(src)}
                chunk = [by_id[i] for i in ids]
                paths = [Path(rec.data_dir) / cap.path for cap in chunk]
                results = measure_stored(paths, c.measure_params, c)
                params_doc = c.measure_params.model_dump(mode="json")
                software = _software()
                ok = 0
                for cap, result in zip(chunk, results, strict=True):
                    result["file"] = cap.path
                    rec.add_measurement(c.session_id, cap.id, result, params=params_doc, software=software)
                    ok += bool(result.get("ok"))
                return {"measured": len(chunk), "ok": ok}

            yield Step(k // CHUNK, f"captures {k + 1}-{k + len(ids)}", (Compute(run),), {"chunk": k // CHUNK})

    def resume_prelude(self, params: ReanalyseParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: ReanalyseParams, ctx: PlanContext) -> ReferencePose | None:
        return None  # no device

    def analyse(
        self, params: ReanalyseParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        from station.plans import get_plan, parse_params

        record = _record(ctx)
        source = record.get_session(params.session)
        plan = get_plan(source.kind)
        source_params = parse_params(plan, source.params.get("plan", {}))
        # the source session's station as it recorded it (its reference pose, the camera's height that
        # chose each excursion's sign, a calibration's cell), never the station of today: a re-analysis
        # moves nothing and computes what the session computed
        sub = PlanContext(
            measure_params=ctx.measure_params,
            reference_joints_deg=reference_of(source.config),
            camera_height_mm=camera_height_of(source.config),
            record=record,
            session_id=source.id,
            jobs=ctx.jobs,
            compute=ctx.compute,
            cancelled=ctx.cancelled,
        )
        recorded = getattr(plan, "analysis_context", None)
        if recorded is not None:
            sub = recorded(source.config, sub)
        inner = plan.analyse(source_params, sub, captures)
        out: dict[str, Any] = {"source_session": source.id, "kind": source.kind, source.kind: inner}
        if "checks" in inner:
            out["checks"] = inner["checks"]  # the source's gates judge the re-analysis too
        return out


def _software() -> str:
    from station import __version__

    return f"station {__version__}"


SWEEP = SweepPlan()
REANALYSE = ReanalysePlan()
