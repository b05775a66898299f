"""How a ``repeatability`` session is reported: the seed's Table 2 (eq. 13: RP = l-bar + 3 S_l) and
Figures 16-17 (each test's attained positions, the RP circle and its interval), and the RP summary."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Wedge
from matplotlib.ticker import MaxNLocator

from station.kinds.repeatability.results import FailedTest, RepeatabilityResults, RepeatabilityTest
from station.reporting._figure import (
    LBAR_C,
    POINT_C,
    RP_C,
    NamedFigure,
    new_figure,
)
from station.reporting._session import Session
from station.reporting._table import (
    Table,
    failures_table,
    make_table,
)


def motion(name: str, t: RepeatabilityTest) -> str:
    """A test's motion in words: 'joint 2, -10 deg' or 'sequence, 3 targets'."""
    if t.kind == "joint":
        joint = "?" if t.joint is None else str(t.joint)
        return f"joint {joint}" + ("" if t.delta_deg is None else f", {t.delta_deg:+g} deg")
    if t.targets_deg is not None:
        return f"{t.kind}, {len(t.targets_deg)} targets"
    return t.kind


def _rp3d_cells(t: RepeatabilityTest | FailedTest | None) -> list[str]:
    if not isinstance(t, RepeatabilityTest):
        return ["", ""]
    if t.rp3d_mm is None:
        return [f"no RP3D: {t.rp3d_error}" if t.rp3d_error else "", ""]
    ci = "" if t.rp3d_ci95_mm is None else f"{t.rp3d_ci95_mm[0]:.5f} - {t.rp3d_ci95_mm[1]:.5f}"
    return [f"{t.rp3d_mm:.5f}", ci]


def repeatability_tables(r: RepeatabilityResults) -> dict[str, Table]:
    """The seed's Table 2 with each test's statistics (eq. 13) and, when given, the seed's RP."""
    seed = r.seed_table2_mm or {}
    headers = ["test", "motion", "l_bar_mm", "S_l_mm", "RP_mm", "RP_95%_mm", "N"]
    if seed:
        headers.append("seed_RP_mm")
    with_z = any(t.rp3d_mm is not None or t.rp3d_error is not None for t in r.measured.values())
    if with_z:
        headers += ["RP3D_mm", "RP3D_95%_mm"]
    rows = []
    names = list(r.tests) + [n for n in r.rp_mm if n not in r.tests]
    failed: list[tuple[str, dict[str, Any]]] = []
    for name in names:
        t = r.tests.get(name)
        if t is None:  # an RP without its test's details (partial results)
            row = [name, "", "", "", f"{r.rp_mm[name]:.5f}", "", ""]
        elif isinstance(t, FailedTest):
            row = [name, f"no RP: {t.error}", "", "", "", "", _n(t.n_cycles, t.planned_cycles, t.partial)]
        else:
            failed += [(name, f) for f in t.failures]
            ci = "" if t.rp_ci95_mm is None else f"{t.rp_ci95_mm[0]:.5f} - {t.rp_ci95_mm[1]:.5f}"
            row = [name, motion(name, t), f"{t.l_bar_mm:.5f}", f"{t.s_l_mm:.5f}", f"{t.rp_mm:.5f}"]
            row += [ci, _n(t.n_cycles, t.planned_cycles, t.partial)]
        if seed:
            row.append(f"{seed[name]:.5f}" if name in seed else "")
        if with_z:
            row += _rp3d_cells(t)
        rows.append(row)
    notes = [
        "RP = l_bar + 3 S_l (seed eq. 13, ISO 9283); S_l with N - 1; l = distance of each attained "
        "position from the barycentre; 95 % interval of RP by bootstrap over the N cycles",
    ]
    if with_z:
        notes.append(
            "RP3D: the same in 3-D, each attained position's (x, y) from the image and z from the distance"
            " sensor"
        )
    partial = [name for name, t in r.tests.items() if getattr(t, "partial", False)]
    if partial:
        notes.append(
            f"partial: {', '.join(partial)} measured fewer cycles than planned (N); their RP is their own "
            "and not in the headline rp_mm"
        )
    conditions = [f"{r.n_cycles} cycles planned per test"] if r.n_cycles is not None else []
    if r.speed_pct is not None:
        conditions.append(f"{r.speed_pct:g} % speed")
    if r.load_kg is not None:
        conditions.append(f"load {r.load_kg:g} kg")
    if conditions:
        notes.append(", ".join(conditions))
    out = {"repeatability": make_table("Repeatability (Table 2)", headers, rows, *notes)}
    if failed:
        out["failures"] = failures_table([f for _, f in failed], [name for name, _ in failed])
    return out


def _n(n: int | None, planned: int | None, partial: bool | None) -> str:
    """A test's N: 'N', or 'N of P (partial)' when fewer cycles were measured than planned."""
    if n is None:
        return ""
    if partial and planned is not None:
        return f"{n} of {planned} (partial)"
    return str(n)


def _panel_limit(tests: Mapping[str, RepeatabilityTest]) -> float:
    """Half-width (um) of every panel of a figure: the largest point, RP or interval, plus a margin."""
    extent = 0.0
    for t in tests.values():
        pts = (np.asarray(t.points_mm, dtype=np.float64).reshape(-1, 2) - t.barycentre_mm) * 1000.0
        extent = max(extent, t.rp_mm * 1000.0, float(np.abs(pts).max(initial=0.0)))
        if t.rp_ci95_mm is not None:
            extent = max(extent, t.rp_ci95_mm[1] * 1000.0)
    return 1.12 * extent if extent > 0 else 1.0


#: Panel grid geometry (inches): panel side, margins for tick labels, titles, suptitle and legend.
_PANEL, _GAP_W, _GAP_H, _LEFT, _RIGHT, _BOTTOM, _TOP = 2.7, 0.35, 0.75, 0.75, 0.2, 0.95, 1.05
#: The narrowest figure (inches): the suptitle and the three-column legend fit across it, so that a
#: figure of one or two panels (``joints=[1]``) cuts neither off; the panels are centred in it.
_MIN_WIDTH = 6.0


def repeatability_figure(tests: Mapping[str, RepeatabilityTest], *, name: str, what: str) -> NamedFigure:
    """Figures 16-17 of the seed: per test, attained positions around the barycentre with the RP circle.

    Every panel of one figure has the same scale (um), so that panels compare at a glance. The layout is
    fixed (no layout engine): it is the costly part of drawing a grid of panels.
    """
    names = list(tests)
    n = len(names)
    ncols = min(3, n)
    nrows = math.ceil(n / ncols)
    grid = _LEFT + _RIGHT + ncols * _PANEL + (ncols - 1) * _GAP_W
    width = max(grid, _MIN_WIDTH)
    side = (width - grid) / 2
    height = _BOTTOM + _TOP + nrows * _PANEL + (nrows - 1) * _GAP_H
    fig = new_figure(width, height, layout=False)
    fig.subplots_adjust(
        left=(_LEFT + side) / width,
        right=1 - (_RIGHT + side) / width,
        bottom=_BOTTOM / height,
        top=1 - _TOP / height,
        wspace=_GAP_W / _PANEL,
        hspace=_GAP_H / _PANEL,
    )
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False)
    lim = _panel_limit(tests)
    locator = MaxNLocator(nbins=4, symmetric=True)
    for i, ax in enumerate(axes.flat):
        if i >= n:
            ax.set_visible(False)
            continue
        _repeatability_panel(ax, names[i], tests[names[i]])
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.xaxis.set_major_locator(locator)
        ax.yaxis.set_major_locator(locator)
        if i % ncols == 0:
            ax.set_ylabel("y − ȳ (µm)")
        if i >= n - ncols:
            ax.set_xlabel("x − x̄ (µm)")
            ax.xaxis.set_tick_params(labelbottom=True)
    handles = [
        Line2D([], [], ls="", marker="o", color=POINT_C, ms=4, alpha=0.7),
        Line2D([], [], ls="", marker="+", color="black", ms=8),
        Line2D([], [], color=RP_C, lw=1.4),
        Patch(color=RP_C, alpha=0.15),
        Line2D([], [], color=LBAR_C, lw=1.0, ls="--"),
    ]
    labels = ["attained position", "barycentre", "RP = l̄ + 3 Sₗ", "95 % interval of RP", "l̄ (mean distance)"]
    fig.legend(handles, labels, loc="lower center", ncols=3 if ncols < 3 else 5, fontsize=8, frameon=False)
    fig.suptitle(f"{what}: attained positions around the barycentre\n(all panels to one scale)", fontsize=11)
    return NamedFigure(
        name,
        f"{what}: attained positions relative to their barycentre with the RP circle, its 95 % interval "
        "and the l̄ circle, one panel per test (seed Figs. 16-17).",
        fig,
    )


def _repeatability_panel(ax: Axes, name: str, t: RepeatabilityTest) -> None:
    pts = (np.asarray(t.points_mm, dtype=np.float64).reshape(-1, 2) - t.barycentre_mm) * 1000.0
    rp, lbar = t.rp_mm * 1000.0, t.l_bar_mm * 1000.0
    if t.rp_ci95_mm is not None:
        lo, hi = (v * 1000.0 for v in t.rp_ci95_mm)
        band = Wedge((0, 0), hi, 0, 360, width=max(hi - lo, 0.0), color=RP_C, alpha=0.15, lw=0)
        band.set_gid(f"rp-interval-{name}")
        ax.add_patch(band)
    rp_circle = Circle((0, 0), rp, fill=False, color=RP_C, lw=1.4)
    rp_circle.set_gid(f"rp-circle-{name}")
    ax.add_patch(rp_circle)
    lbar_circle = Circle((0, 0), lbar, fill=False, color=LBAR_C, lw=1.0, ls="--")
    lbar_circle.set_gid(f"lbar-circle-{name}")
    ax.add_patch(lbar_circle)
    ax.plot(pts[:, 0], pts[:, 1], "o", color=POINT_C, ms=3, alpha=0.7)
    ax.plot([0], [0], "+", color="black", ms=8)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_title(f"{name}: {motion(name, t)}\nRP {rp:.2f} µm, l̄ {lbar:.2f} µm, N = {t.n_cycles}", fontsize=9)


def rp_summary_figure(r: RepeatabilityResults) -> NamedFigure:
    """RP per test with its 95 % interval, beside the seed's Table 2 where given."""
    tests = r.measured
    names = list(tests) + [k for k in r.rp_mm if k not in tests]
    rp = np.array([tests[k].rp_mm if k in tests else r.rp_mm[k] for k in names]) * 1000.0
    fig = new_figure(max(4.0, 0.7 * len(names) + 2.0), 3.8)
    ax = fig.add_subplot()
    x = np.arange(len(names))
    ax.bar(x, rp, width=0.6, color=POINT_C, alpha=0.8, label="RP, this session")
    lo = [tests[k].rp_ci95_mm if k in tests else None for k in names]
    have = [i for i, c in enumerate(lo) if c is not None]
    if have:
        cis = np.array([lo[i] for i in have], dtype=np.float64) * 1000.0
        yerr = np.vstack([rp[have] - cis[:, 0], cis[:, 1] - rp[have]]).clip(min=0)
        ax.errorbar(
            x[have], rp[have], yerr=yerr, fmt="none", ecolor="black", capsize=4, lw=1, label="95 % interval"
        )
    seed = r.seed_table2_mm or {}
    at = [i for i, k in enumerate(names) if k in seed]
    if at:
        ax.plot(
            x[at],
            [seed[names[i]] * 1000.0 for i in at],
            "D",
            color="black",
            mfc="white",
            ms=6,
            label="seed (Table 2)",
        )
    ax.set_xticks(x, names)
    ax.set_xlabel("test")
    ax.set_ylabel("RP (µm)")
    ax.set_ylim(bottom=0)
    ax.grid(True, axis="y", lw=0.4, alpha=0.5)
    ax.legend(fontsize=8)
    ax.set_title("Pose repeatability per test (RP = l̄ + 3 Sₗ)", fontsize=10)
    return NamedFigure("repeatability-rp", "RP per test with its 95 % interval (Table 2).", fig)


def tables(r: RepeatabilityResults, s: Session) -> dict[str, Table]:
    """The kind's report tables (``Kind.tables``)."""
    return repeatability_tables(r)


def figures(r: RepeatabilityResults) -> list[NamedFigure]:
    """Figure 16 (joint tests), 17 (sequences) and the RP summary, for what was measured."""
    joints = {k: t for k, t in r.measured.items() if t.kind == "joint"}
    others = {k: t for k, t in r.measured.items() if t.kind != "joint"}
    out = []
    if joints:
        out.append(repeatability_figure(joints, name="repeatability-joints", what="Joint tests"))
    if others:
        out.append(repeatability_figure(others, name="repeatability-sequences", what="Sequences"))
    if r.measured or r.rp_mm:
        out.append(rp_summary_figure(r))
    return out
