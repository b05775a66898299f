"""How a ``sweep`` session is reported: Table 1 as ``station sweep`` prints it, the seed's beside it,
and MeanE / MaxE per trial as a bar chart."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from station.kinds.sweep.results import SweepResults
from station.parameter_study import SEED_TABLE_1
from station.reporting._figure import (
    MAX_C,
    MEAN_C,
    NamedFigure,
    new_figure,
)
from station.reporting._session import Session
from station.reporting._table import (
    Table,
    make_table,
    tuples,
)
from station.text_tables import SweepRow, is_seed_table_1, seed_table_1, sweep_note, sweep_table


def sweep_fit(r: SweepResults) -> str:
    """Which errors Table 1 shows: the seed's ``parallelogram`` when every measured trial recorded them,
    else ``rigid`` (``mean_um`` / ``max_um``)."""
    ok = [t for t in r.trials if t.mean_um is not None or t.parallelogram_mean_um is not None]
    if all(t.parallelogram_mean_um is not None and t.parallelogram_max_um is not None for t in ok):
        return "parallelogram"
    return "rigid"


def sweep_errors_um(r: SweepResults) -> list[tuple[float | None, float | None]]:
    """(MeanE, MaxE) per trial in um, after the fit ``sweep_fit`` chose; None where the trial failed."""
    if sweep_fit(r) == "parallelogram":
        return [(t.parallelogram_mean_um, t.parallelogram_max_um) for t in r.trials]
    return [(t.mean_um, t.max_um) for t in r.trials]


def sweep_rows(r: SweepResults) -> list[SweepRow]:
    """A sweep session's trials as Table 1 rows (um -> mm)."""
    return [
        SweepRow(
            t.number,
            t.overrides,
            None if mx is None else mx / 1000.0,
            None if mean is None else mean / 1000.0,
            t.error,
        )
        for t, (mean, mx) in zip(r.trials, sweep_errors_um(r), strict=True)
    ]


def sweep_tables(r: SweepResults, mode: str | None) -> dict[str, Table]:
    """Table 1 as ``station sweep`` prints it, best trial marked, and the seed's own beside it."""
    seed_layout = is_seed_table_1([t.overrides for t in r.trials])
    headers, rows = sweep_table(sweep_rows(r), r.best, seed_layout=seed_layout)
    marked = frozenset(i for i, t in enumerate(r.trials) if t.number == r.best)
    notes = sweep_note(mode, seed_layout=seed_layout, fit=sweep_fit(r)).split("\n")
    if r.source_session is not None:
        notes.append(f"images of validation session {r.source_session}")
    if r.sessions is not None:
        notes.append(
            f"images of {len(r.sessions)} validation sessions: MeanE over all their positions (each "
            "session's weighted by its positions), MaxE the largest of any session"
        )
    out = {"sweep": Table("Parameter study (Table 1)", tuple(headers), tuples(rows), tuple(notes), marked)}
    if r.sessions is not None:
        out["sweep_sessions"] = session_table(r)
    if seed_layout:
        out["seed_table_1"] = make_table("The seed's Table 1", *seed_table_1())
    return out


def session_table(r: SweepResults) -> Table:
    """Each session of a selection: its positions, and each trial's MeanE / MaxE there (um, after the fit
    Table 1 uses); the best trial's column first after the positions."""
    fit = "parallelogram_" if sweep_fit(r) == "parallelogram" else ""
    order = sorted(r.trials, key=lambda t: t.number != r.best)
    headers = [
        "session",
        "positions",
        *(f"trial {t.number}{' (best)' if t.number == r.best else ''}" for t in order),
    ]
    cells: dict[str, dict[int, str]] = {}
    positions: dict[str, int] = {}
    for t in r.trials:
        for s in t.sessions or []:
            mean, mx = getattr(s, f"{fit}mean_um"), getattr(s, f"{fit}max_um")
            cells.setdefault(s.session, {})[t.number] = (
                "failed" if mean is None or mx is None else f"{mean:.3f} / {mx:.3f}"
            )
            positions[s.session] = max(positions.get(s.session, 0), s.positions)
    rows = [
        (sid, str(positions.get(sid, 0)), *(cells.get(sid, {}).get(t.number, "-") for t in order))
        for sid in r.sessions or []
    ]
    return make_table(
        "Parameter study per session (MeanE / MaxE, um)",
        headers,
        rows,
        f"errors after the {sweep_fit(r)} fit, each session's positions on their own",
    )


def sweep_figure(r: SweepResults) -> NamedFigure:
    """Table 1 as bars: MeanE and MaxE (um, after the fit the table uses) per trial; the best marked."""
    trials = r.trials
    x = np.arange(len(trials))
    errors = sweep_errors_um(r)
    mean = np.array([np.nan if m is None else m for m, _ in errors], dtype=np.float64)
    mx = np.array([np.nan if m is None else m for _, m in errors], dtype=np.float64)
    fit = sweep_fit(r)
    fig = new_figure(max(5.0, 0.6 * len(trials) + 2.5), 4.0)
    ax = fig.add_subplot()
    w = 0.38
    ax.bar(x - w / 2, np.nan_to_num(mean), w, color=MEAN_C, label="MeanE")
    ax.bar(x + w / 2, np.nan_to_num(mx), w, color=MAX_C, label="MaxE")
    top = float(np.nanmax(mx)) if np.isfinite(mx).any() else 1.0
    if is_seed_table_1([t.overrides for t in trials]):
        seed_label = "seed's Table 1 (over each bar)"
        if fit != "parallelogram":
            seed_label = "seed's Table 1 (parallelogram fit)"
        seed_mean = [row[6] * 1000.0 for row in SEED_TABLE_1]
        seed_max = [row[5] * 1000.0 for row in SEED_TABLE_1]
        ax.plot(x - w / 2, seed_mean, "_", color="black", ms=14, mew=2)
        ax.plot(x + w / 2, seed_max, "_", color="black", ms=14, mew=2, label=seed_label)
        top = max(top, *seed_max)
    for i in range(len(trials)):
        if not (np.isfinite(mean[i]) and np.isfinite(mx[i])):
            ax.text(
                x[i], 0.02 * top, "failed", rotation=90, ha="center", va="bottom", fontsize=8, color="black"
            )
    ax.set_xticks(x, [str(t.number) + (" ★" if t.number == r.best else "") for t in trials])
    for lbl, t in zip(ax.get_xticklabels(), trials, strict=True):
        if t.number == r.best:
            lbl.set_fontweight("bold")
    ax.set_xlabel("trial (★ best: lowest MeanE, then MaxE)")
    ax.set_ylabel(f"error after {fit} fit (µm)")
    ax.set_ylim(0, top * 1.15)
    ax.grid(True, axis="y", lw=0.4, alpha=0.5)
    ax.legend(fontsize=8)
    ax.set_title("Parameter study: MeanE / MaxE per trial (Table 1)", fontsize=10)
    return NamedFigure("sweep", f"MeanE and MaxE per trial after the {fit} fit (Table 1).", fig)


def tables(r: SweepResults, s: Session) -> dict[str, Table]:
    """The kind's report tables (``Kind.tables``): Table 1 under the session's measurement mode."""
    measure = s.params.get("measure")
    mode = measure.get("mode") if isinstance(measure, Mapping) else s.params.get("mode")
    return sweep_tables(r, None if mode is None else str(mode))


def figures(r: SweepResults) -> list[NamedFigure]:
    return [sweep_figure(r)] if r.trials else []
