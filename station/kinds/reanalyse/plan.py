"""The ``reanalyse`` kind's plan: any stored session (or an archive selection of them) measured again with
other parameters or software, on the session's compute backend (``station.compute``: the local pool by
default, or a Dask cluster), then analysed as its own kind. With the same parameters and software it
reproduces the stored results bit for bit, on any backend.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

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
from station.plans._recorded import camera_height_of, record_of, reference_of, stored_captures
from station.plans._ruler import capture_params
from station.plans._selection import (
    Source,
    SourceParams,
    missing_images,
    resolve,
)
from station.record import CaptureRow, Record, SessionRow
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


class ReanalyseParams(SourceParams):
    """What a re-analysis reads: one stored session, or an archive selection (``SourceParams``)."""


class ReanalysePlan:
    name = "reanalyse"
    Params = ReanalyseParams
    needs: frozenset[str] = frozenset()

    def source_session(self, params: ReanalyseParams) -> str | None:
        """The one stored session it reads; None for a selection (its analysis reads each source)."""
        return params.session

    def sources(self, params: ReanalyseParams, ctx: PlanContext) -> list[Source]:
        """The sessions it reads, each checked (PlanError listing every one that cannot be)."""
        record = record_of(ctx)
        plan_of = ctx.plan_of

        def fits(kind: str) -> str | None:
            if plan_of is None:
                return "a re-analysis needs the kinds' registry (PlanContext.plan_of)"
            try:
                plan = plan_of(kind)
            except PlanError as exc:
                return f"{exc}; this software cannot analyse it: leave it out of the selection"
            if not plan.needs:
                return f"a {kind} session captures nothing to measure again: leave it out of the selection"
            return None

        before = None if ctx.session_id is None else record.get_session(ctx.session_id).created_at
        return resolve(
            record,
            session=params.session,
            sessions=params.sessions,
            select=params.select,
            fits=fits if params.session is None else _any_kind,
            read=_captures,
            created_before=before,
        )

    def steps(self, params: ReanalyseParams, ctx: PlanContext) -> Iterator[Step]:
        sources = self.sources(params, ctx)  # every session checked before any task is sent
        # the captures of every source in turn, CHUNK per step: small sessions share a step (and the
        # backend's tasks), measured together wherever they are measured with the same parameters
        work = [(source.session, cap) for source in sources for cap in source.captures]
        for k in range(0, len(work), CHUNK):
            chunk = work[k : k + CHUNK]

            def run(c: PlanContext, chunk: list[tuple[SessionRow, CaptureRow]] = chunk) -> dict[str, Any]:
                rec = record_of(c)
                assert c.session_id is not None
                software = _software()
                ok = 0
                for measure, caps in self._by_params(params, chunk, c):
                    paths = [Path(rec.data_dir) / cap.path for cap in caps]
                    results = measure_stored(paths, measure, c)
                    params_doc = measure.model_dump(mode="json")
                    for cap, result in zip(caps, results, strict=True):
                        result["file"] = cap.path
                        rec.add_measurement(
                            c.session_id, cap.id, result, params=params_doc, software=software
                        )
                        ok += bool(result.get("ok"))
                return {"measured": len(chunk), "ok": ok}

            name = f"captures {k + 1}-{k + len(chunk)}" + (
                "" if params.session is not None else " of the selection"
            )
            yield Step(k // CHUNK, name, (Compute(run),), {"chunk": k // CHUNK})

    @staticmethod
    def _by_params(
        params: ReanalyseParams, chunk: Sequence[tuple[SessionRow, CaptureRow]], ctx: PlanContext
    ) -> list[tuple[MeasureParams | RulerParams, list[CaptureRow]]]:
        """A step's captures in runs measured with the same parameters (one source's, or several
        consecutive sources' that recorded the same; a ruler's frame with measure_ruler's)."""
        own: dict[str, MeasureParams] = {}
        runs: list[tuple[MeasureParams | RulerParams, list[CaptureRow]]] = []
        for row, cap in chunk:
            if params.session is not None:
                base = ctx.measure_params
            else:
                if row.id not in own:
                    own[row.id] = own_params(row, ctx)
                base = own[row.id]
            measure = capture_params(cap.meta, base, (cap.height, cap.width))
            if runs and runs[-1][0] == measure:
                runs[-1][1].append(cap)
            else:
                runs.append((measure, [cap]))
        return runs

    def resume_prelude(self, params: ReanalyseParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: ReanalyseParams, ctx: PlanContext) -> ReferencePose | None:
        return None  # no device

    def analyse(
        self, params: ReanalyseParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        record = record_of(ctx)
        if params.session is not None:
            return self._analyse_one(record.get_session(params.session), ctx, captures)
        # a selection: each source analysed as its own kind on what this session measured of it
        assert ctx.session_id is not None
        out = []
        measured = {m.capture_id: m for m in record.measurements(ctx.session_id)}  # read once, not per source
        for source in self.sources(params, ctx):
            caps = stored_captures(record, source.session.id, measurements=measured)
            own = replace(ctx, measure_params=own_params(source.session, ctx))
            out.append(self._analyse_one(source.session, own, caps))
        return {"sessions": out, "checks": [c for one in out for c in _named_checks(one)]}

    def _analyse_one(
        self, source: SessionRow, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        record = record_of(ctx)
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


def own_params(source: SessionRow, ctx: PlanContext) -> MeasureParams:
    """A source's measurement parameters in a selection: those it recorded, with what this session's
    parameters set differently from the defaults (the configuration's, ``--set``) on top; with nothing
    set, each source is measured as it was and gives its stored results."""
    default = MeasureParams().model_dump(mode="json")
    changed = {k: v for k, v in ctx.measure_params.model_dump(mode="json").items() if v != default.get(k)}
    return MeasureParams.model_validate({**source.params.get("measure", {}), **changed})


def _any_kind(kind: str) -> str | None:
    return None  # one named session: any kind (one without captures says so)


def _captures(row: SessionRow, record: Record) -> tuple[CaptureRow, ...] | str:
    """A session's captures to measure again, or why there are none to measure."""
    caps = tuple(record.captures(row.id))
    if not caps:
        return "it has no captures to measure again: leave it out of the selection"
    return missing_images(record, caps) or caps


def _named_checks(one: dict[str, Any]) -> list[dict[str, Any]]:
    """A source's checks, each named after its session (a selection's gates judge every source)."""
    return [{**c, "name": f"{one['source_session']}: {c['name']}"} for c in one.get("checks", [])]


def _software() -> str:
    from station import __version__

    return f"station {__version__}"


REANALYSE = ReanalysePlan()
