"""The ``reanalyse`` kind's plan: any stored session measured again with other parameters or software, on
the session's compute backend (``station.compute``: the local pool by default, or a Dask cluster), then
analysed as its own kind. With the same parameters and software it reproduces the stored results bit for
bit, on any backend.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from station.compute import LocalBackend
from station.plans import (
    CaptureResult,
    Compute,
    PlanContext,
    PlanError,
    ReferencePose,
    Step,
    parse_params,
    station_cell,
)
from station.plans._recorded import camera_height_of, record_of, reference_of
from station.plans._ruler import capture_params
from station.vision import MeasureParams, RulerParams

CHUNK = 64  # captures per reanalysis step: the runner's pause/stop granularity


def measure_stored(
    paths: Sequence[Path], params: MeasureParams | RulerParams, ctx: PlanContext
) -> list[dict[str, Any]]:
    """Measure stored image files on the session's backend (else a local pool of ``ctx.jobs``);
    ``station measure --json`` objects, in order."""
    if ctx.compute is not None:
        return [r.to_json() for r in ctx.compute.measure(paths, params, cancelled=ctx.cancelled)]
    with contextlib.closing(LocalBackend(ctx.jobs)) as local:
        return [r.to_json() for r in local.measure(paths, params, cancelled=ctx.cancelled)]


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
        record = record_of(ctx)
        source = record.get_session(params.session)
        caps = record.captures(source.id)
        if not caps:
            raise PlanError(f"session {source.id} has no captures to measure again")
        for k in range(0, len(caps), CHUNK):
            ids = [c.id for c in caps[k : k + CHUNK]]

            def run(c: PlanContext, ids: list[int] = ids, src: str = source.id) -> dict[str, Any]:
                rec = record_of(c)
                assert c.session_id is not None
                by_id = {cap.id: cap for cap in rec.captures(src)}
                chunk = [by_id[i] for i in ids]
                # each capture with what the session measured it with: a ruler's frame with measure_ruler's
                groups: dict[str, tuple[MeasureParams | RulerParams, list[int]]] = {}
                for j, cap in enumerate(chunk):
                    p = capture_params(cap.meta, c.measure_params, (cap.height, cap.width))
                    groups.setdefault(p.model_dump_json(), (p, []))[1].append(j)
                results: list[dict[str, Any]] = [{} for _ in chunk]
                docs: list[dict[str, Any]] = [{} for _ in chunk]
                for p, rows in groups.values():
                    paths = [Path(rec.data_dir) / chunk[j].path for j in rows]
                    for j, result in zip(rows, measure_stored(paths, p, c), strict=True):
                        results[j], docs[j] = result, p.model_dump(mode="json")
                software = _software()
                ok = 0
                for cap, result, params_doc in zip(chunk, results, docs, strict=True):
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
        record = record_of(ctx)
        source = record.get_session(params.session)
        if ctx.plan_of is None:
            raise PlanError("a re-analysis needs the kinds' registry (PlanContext.plan_of)")
        plan = ctx.plan_of(source.kind)
        source_params = parse_params(plan, source.params.get("plan", {}))
        # the source session's station as it recorded it (its reference pose, the camera's height that
        # chose each excursion's sign, a calibration's cell), never the station of today: a re-analysis
        # moves nothing and computes what the session computed
        sub = PlanContext(
            measure_params=ctx.measure_params,
            reference_joints_deg=reference_of(source.config),
            camera_height_mm=camera_height_of(source.config),
            record=record,
            cell=station_cell(plan, source.config, ctx.measure_params),
            session_id=source.id,
            jobs=ctx.jobs,
            compute=ctx.compute,
            cancelled=ctx.cancelled,
            plan_of=ctx.plan_of,
        )
        inner = plan.analyse(source_params, sub, captures)
        out: dict[str, Any] = {"source_session": source.id, "kind": source.kind, source.kind: inner}
        if "checks" in inner:
            out["checks"] = inner["checks"]  # the source's gates judge the re-analysis too
        return out


def _software() -> str:
    from station import __version__

    return f"station {__version__}"


REANALYSE = ReanalysePlan()
