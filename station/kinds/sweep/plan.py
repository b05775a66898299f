"""The ``sweep`` kind's plan: a stored validation session, or an archive selection of them, re-measured
over a parameter grid (default: the seed's Table 1 trials) with the ``station sweep`` core, one step per
trial (per trial and session over a selection: ``archive``), ranked over every session."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any, Literal

from pydantic import (
    Field,
    field_validator,
)

from station.displacements import CALIBRATIONS
from station.imagesets import ImageSet
from station.kinds.sweep.archive import (
    FIGURES,
    groups,
    image_set_of,
    pooled,
    position_captures,
    sweep_fits,
    trial_figures,
    trial_on_group,
)
from station.parameter_study import grid, run_sweep, seed_trials
from station.plans import CaptureResult, Compute, PlanContext, PlanError, ReferencePose, Step
from station.plans._recorded import record_of
from station.plans._selection import Source, SourceParams, resolve
from station.vision import field_name


class SweepParams(SourceParams):
    session: str | None = Field(
        None, min_length=4, description="id (or unique prefix) of a stored validation session"
    )
    sessions: list[str] | None = Field(
        None, description="an archive selection by ids (or unique prefixes) of stored validation sessions"
    )
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

    def source_session(self, params: SweepParams) -> str | None:
        """The one stored session a sweep reads; None for a selection (its analysis reads the steps)."""
        return params.session

    def sources(self, params: SweepParams, ctx: PlanContext) -> list[Source]:
        """The sessions the sweep reads, each checked (PlanError listing every one that cannot be)."""
        record = record_of(ctx)
        before = None if ctx.session_id is None else record.get_session(ctx.session_id).created_at
        return resolve(
            record,
            session=params.session,
            sessions=params.sessions,
            select=params.select,
            fits=sweep_fits,
            read=position_captures,
            created_before=before,
        )

    def image_set(self, params: SweepParams, ctx: PlanContext) -> ImageSet:
        """The single source's image set (a sweep of one session)."""
        return image_set_of(self.sources(params, ctx)[0], record_of(ctx))

    def overrides(self, params: SweepParams) -> list[dict[str, Any]]:
        return grid(params.grid) if params.grid is not None else seed_trials()

    def steps(self, params: SweepParams, ctx: PlanContext) -> Iterator[Step]:
        if params.calibration not in CALIBRATIONS:
            raise PlanError(f"calibration must be one of {CALIBRATIONS}")
        sources = self.sources(params, ctx)  # every session checked before any trial is sent
        if params.session is None:
            yield from self._selection_steps(params, sources)
            return
        (source,) = sources
        for number, change in enumerate(self.overrides(params), start=1):

            def run(c: PlanContext, change: dict[str, Any] = change, number: int = number) -> dict[str, Any]:
                trial = run_sweep(
                    image_set_of(source, record_of(c)),
                    c.measure_params,
                    [change],
                    jobs=c.jobs,
                    backend=c.compute,
                    calibration=params.calibration,
                )[0]
                doc = {"number": number, "overrides": change, **trial_figures(trial)}
                doc.pop("positions")  # one session: the trial's figures are its own (as they always were)
                return doc

            yield Step(number - 1, f"trial {number}", (Compute(run, f"trial {number}"),), {"trial": number})

    def _selection_steps(self, params: SweepParams, sources: list[Source]) -> Iterator[Step]:
        """A step per trial and group of sessions: the group's frames measured in one call."""
        parts = groups(sources)
        for number, change in enumerate(self.overrides(params), start=1):
            for g, group in enumerate(parts):

                def run(
                    c: PlanContext,
                    change: dict[str, Any] = change,
                    number: int = number,
                    group: tuple[Source, ...] = group,
                ) -> dict[str, Any]:
                    docs = trial_on_group(
                        group,
                        record_of(c),
                        c.measure_params,
                        change,
                        jobs=c.jobs,
                        backend=c.compute,
                        calibration=params.calibration,
                        cancelled=c.cancelled,
                    )
                    return {"number": number, "overrides": change, "sessions": docs}

                ids = [s.session.id for s in group]
                name = f"trial {number}, sessions {ids[0]}" + (f"-{ids[-1]}" if len(ids) > 1 else "")
                yield Step((number - 1) * len(parts) + g, name, (Compute(run, name),), {"trial": number})

    def resume_prelude(self, params: SweepParams, ctx: PlanContext, next_step: Step) -> list[Step]:
        return []

    def reference_pose(self, params: SweepParams, ctx: PlanContext) -> ReferencePose | None:
        return None  # no device

    def analyse(
        self, params: SweepParams, ctx: PlanContext, captures: Sequence[CaptureResult]
    ) -> dict[str, Any]:
        record = record_of(ctx)
        assert ctx.session_id is not None
        rows = [s for s in record.steps(ctx.session_id) if s.state == "done" and "number" in s.data]
        done = [s.data for s in sorted(rows, key=lambda s: s.index)]
        if params.session is not None:
            trials = sorted(done, key=lambda t: t["number"])
            source: str | None = record.get_session(params.session).id
            sessions = None
        else:
            # a selection: each trial's per-session figures, in the selection's order, pooled
            by_trial: dict[int, list[dict[str, Any]]] = {}
            for t in done:
                by_trial.setdefault(t["number"], []).extend(
                    {k: s[k] for k in ("session", "error", "positions", *FIGURES)} for s in t["sessions"]
                )
            sessions = [s["session"] for s in next(iter(by_trial.values()), [])]
            overrides = {t["number"]: t["overrides"] for t in done}
            trials = [pooled(n, overrides[n], by_trial[n]) for n in sorted(by_trial)]
            source = None
        # the seed's Table 1 ranks by MeanE then MaxE after the well-fit parallelogram (station sweep too)
        ok = [t for t in trials if t.get("parallelogram_mean_um") is not None]
        key = lambda t: (round(t["parallelogram_mean_um"], 4), t["parallelogram_max_um"])  # noqa: E731
        best = min(ok, key=key)["number"] if ok else None
        out: dict[str, Any] = {"trials": trials, "best": best, "source_session": source}
        if sessions is not None:
            out["sessions"] = sessions
        return out


SWEEP = SweepPlan()
