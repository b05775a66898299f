"""The seed's figures, drawn on ``matplotlib.figure.Figure`` objects with the Agg canvas.

Never pyplot: each figure is its own object with its own canvas, so nothing global (current figure, rc
state) leaks between reports or threads.

* Figures 14-15 (validation): the table positions after the best fit (rigid for the raw errors, affine for
  the seed's parallelogram) in the measured, artifact axes, with error lines to the measured positions,
  magnified by a stated factor; a scale bar gives the true error length.
* Figures 16-17 (repeatability): per test, the attained positions relative to their barycentre in um, the
  RP circle (RP = l-bar + 3 S_l), its 95 % interval and the l-bar circle, all panels on one scale.
* Table 1 (sweep) as a bar chart of MeanE / MaxE per trial, the best marked.
* Calibration: the residuals and the relative error before / after (log scale); each parameter's
  estimate - nominal with its 95 % interval, grouped DH / tool / artifacts and split by unit; the singular
  value spectrum of the scaled Jacobian with the rcond line.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch, Wedge
from matplotlib.ticker import MaxNLocator
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

from station.calibration import ResidualSummary as CalibrationResiduals
from station.kinds.calibration.results import CalibrationParameter, CalibrationResults
from station.kinds.repeatability.results import RepeatabilityResults, RepeatabilityTest
from station.kinds.sweep.results import SweepResults
from station.kinds.validation.results import ValidationResults
from station.report import is_seed_table_1
from station.reporting._tables import motion, parameter_group, sweep_errors_um, sweep_fit
from station.sweep import SEED_TABLE_1

#: Colours (matplotlib's tab palette): table/fit, measured/error, RP, l-bar.
TABLE_C, ERROR_C, RP_C, LBAR_C, POINT_C = "#555555", "#d62728", "#d62728", "#7f7f7f", "#1f77b4"
MEAN_C, MAX_C = "#1f77b4", "#ff7f0e"
#: Calibration: nominal model (before), calibrated (after), the floor; structural parameters.
BEFORE_C, AFTER_C, FLOOR_C, STRUCT_C = "#d62728", "#2ca02c", "#7f7f7f", "#9467bd"


@dataclass(frozen=True)
class NamedFigure:
    """A figure with the file stem it is written under and its caption in the report."""

    name: str
    caption: str
    figure: Figure


def _figure(width_in: float, height_in: float, *, layout: bool = True) -> Figure:
    fig = Figure(figsize=(width_in, height_in), layout="constrained" if layout else None)
    FigureCanvasAgg(fig)
    return fig


def nice_floor(x: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``x`` (x > 0)."""
    k = math.floor(math.log10(x))
    for m in (5.0, 2.0, 1.0):
        if m * 10.0**k <= x * (1 + 1e-9):
            return m * 10.0**k
    return 10.0**k  # pragma: no cover  (m = 1 always fits)


def magnification(span: float, max_error: float, *, fraction: float = 0.15) -> float:
    """A round factor drawing the largest error as about ``fraction`` of the pattern's span (>= 1)."""
    if max_error <= 0 or span <= 0 or not math.isfinite(max_error):
        return 1.0
    return max(1.0, nice_floor(fraction * span / max_error))


def _fmt_mag(mag: float) -> str:
    return f"{mag:,.0f}" if mag >= 1 else f"{mag:g}"


def validation_figure(r: ValidationResults, *, fit: str) -> NamedFigure:
    """Figure 14 (``fit="raw"``, rigid) or 15 (``fit="parallelogram"``, affine) of the seed."""
    if fit not in ("raw", "parallelogram"):
        raise ValueError(f"fit must be 'raw' or 'parallelogram', got {fit!r}")
    measured = np.array([p.measured_um for p in r.positions], dtype=np.float64).reshape(-1, 2)
    if fit == "raw":
        err = np.array([p.error_um for p in r.positions], dtype=np.float64).reshape(-1, 2)
        label, mean, mx = "rigid fit", r.rigid.mean_um, r.rigid.max_um
        title = "Raw: measured vs table positions (rigid fit)"
    else:
        if r.affine is None:
            raise ValueError("these results have no parallelogram fit (positions on a line)")
        err = np.array([p.error_parallelogram_um for p in r.positions], dtype=np.float64).reshape(-1, 2)
        label, mean, mx = "parallelogram fit", r.affine.mean_um, r.affine.max_um
        title = "Parallelogram: measured vs table positions (affine fit)"
    fitted = measured - err  # the commanded positions mapped by the fit into the measured axes
    lengths = np.hypot(err[:, 0], err[:, 1])
    span = float(np.ptp(fitted, axis=0).max()) if len(fitted) else 0.0
    mag = magnification(span, float(lengths.max()) if len(lengths) else 0.0)
    shown = fitted + mag * err

    fig = _figure(6.4, 6.4)
    ax = fig.add_subplot()
    ax.plot(fitted[:, 0], fitted[:, 1], "-", color=TABLE_C, lw=0.6, alpha=0.6, zorder=1)
    ax.plot(fitted[:, 0], fitted[:, 1], "o", mfc="white", mec=TABLE_C, ms=5, zorder=2)
    ax.add_collection(
        LineCollection(list(np.stack([fitted, shown], axis=1)), colors=ERROR_C, lw=1.2, zorder=3)
    )
    ax.plot(shown[:, 0], shown[:, 1], ".", color=ERROR_C, ms=5, zorder=4)
    if len(fitted):
        ax.annotate(
            f"#{r.positions[0].index}",
            fitted[0],
            xytext=(-6, -6),
            textcoords="offset points",
            ha="right",
            va="top",
            fontsize=8,
            color=TABLE_C,
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (µm, artifact axes)")
    ax.set_ylabel("y (µm, artifact axes)")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_title(f"{title}\nmean {mean:.4f} µm, max {mx:.4f} µm; error lines ×{_fmt_mag(mag)}", fontsize=10)
    handles = [
        Line2D([], [], ls="-", marker="o", mfc="white", mec=TABLE_C, color=TABLE_C, lw=0.6, ms=5),
        Line2D([], [], ls="-", marker=".", color=ERROR_C, lw=1.2, ms=5),
    ]
    labels = [f"table positions ({label})", f"measured, error ×{_fmt_mag(mag)}"]
    ax.legend(handles, labels, loc="center", fontsize=8, framealpha=0.9)
    if len(lengths) and lengths.max() > 0:
        ref = nice_floor(float(lengths.max()))
        bar = AnchoredSizeBar(
            ax.transData,
            ref * mag,
            f"{ref:g} µm error",
            loc="lower right",
            pad=0.4,
            borderpad=0.5,
            sep=4,
            color=ERROR_C,
            frameon=False,
            size_vertical=0,
            fontproperties={"size": 8},
        )
        ax.add_artist(bar)
    ax.autoscale_view()
    ax.margins(0.08)
    return NamedFigure(
        f"validation-{fit}",
        f"Measured vs table positions after the {label} (seed Fig. {14 if fit == 'raw' else 15}); "
        f"error lines magnified ×{_fmt_mag(mag)}.",
        fig,
    )


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
    fig = _figure(width, height, layout=False)
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
    fig = _figure(max(4.0, 0.7 * len(names) + 2.0), 3.8)
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


def sweep_figure(r: SweepResults) -> NamedFigure:
    """Table 1 as bars: MeanE and MaxE (um, after the fit the table uses) per trial; the best marked."""
    trials = r.trials
    x = np.arange(len(trials))
    errors = sweep_errors_um(r)
    mean = np.array([np.nan if m is None else m for m, _ in errors], dtype=np.float64)
    mx = np.array([np.nan if m is None else m for _, m in errors], dtype=np.float64)
    fit = sweep_fit(r)
    fig = _figure(max(5.0, 0.6 * len(trials) + 2.5), 4.0)
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


def _bars(ax: Axes, labels: list[str], before: list[float | None], after: list[float | None]) -> None:
    x = np.arange(len(labels))
    w = 0.38
    for off, values, colour, name in ((-w / 2, before, BEFORE_C, "before"), (w / 2, after, AFTER_C, "after")):
        v = np.array([np.nan if a is None else a for a in values], dtype=np.float64)
        bars = ax.bar(x + off, np.where(np.isfinite(v), v, 0.0), w, color=colour, label=f"{name}")
        for i, patch in enumerate(bars.patches):
            patch.set_gid(f"bar-{name}-{i}")
        for xi, vi in zip(x + off, v, strict=True):
            if np.isfinite(vi):
                ax.annotate(
                    f"{vi:.0f}" if vi >= 100 else f"{vi:.3g}",
                    (xi, vi),
                    xytext=(0, 2),
                    textcoords="offset points",
                    ha="center",
                    va="bottom",
                    fontsize=7,
                )
    ax.set_xticks(x, labels, fontsize=8)
    ax.set_yscale("log")
    ax.grid(True, axis="y", which="both", lw=0.3, alpha=0.5)


def _um_or_none(v: float | None) -> float | None:
    return None if v is None else v * 1000.0


def calibration_residuals_figure(r: CalibrationResults) -> NamedFigure:
    """Residuals (RMS and largest, xy and z, fitted and held out) and the relative error, before and after,
    on log scales; the relative error's floor as a line."""
    c = r.calibration
    sets: list[tuple[str, CalibrationResiduals | None, CalibrationResiduals | None]] = [
        ("fitted", c.residuals.get("before"), c.residuals.get("after"))
    ]
    cv = c.cross_validation
    if cv is not None and (cv.before is not None or cv.after is not None):
        sets.append(("held out", cv.before, cv.after))
    labels: list[str] = []
    before: list[float | None] = []
    after: list[float | None] = []
    for name, b, a in sets:
        for stat in ("rms_xy_mm", "max_xy_mm", "rms_z_mm", "max_z_mm"):
            labels.append(f"{name}\n{stat[:-3].replace('_', ' ')}")
            before.append(None if b is None else _um_or_none(getattr(b, stat)))
            after.append(None if a is None else _um_or_none(getattr(a, stat)))
    fig = _figure(9.6, 4.2)
    ax1, ax2 = fig.subplots(1, 2, width_ratios=[3, 1])
    _bars(ax1, labels, before, after)
    ax1.set_ylabel("residual (µm)")
    ax1.legend(fontsize=8, loc="upper right")
    ax1.set_title("Residuals, nominal (before) vs calibrated (after) model", fontsize=10)
    e = r.relative_error_um
    _bars(ax2, ["relative\nerror"], [e.before], [e.after])
    if e.floor is not None:
        floor = ax2.axhline(e.floor, color=FLOOR_C, ls="--", lw=1.2, label=f"floor {e.floor:.3g} µm")
        floor.set_gid("relative-error-floor")
        ax2.legend(fontsize=8, loc="upper right")
    ax2.set_ylabel("mean in-plane distance (µm)")
    ax2.set_title("Held-out pairs", fontsize=10)
    for ax in (ax1, ax2):
        lo, hi = ax.get_ylim()
        if ax is ax2 and e.floor is not None and e.floor > 0:
            lo = min(lo, e.floor / 2)
        ax.set_ylim(lo, hi * 3)  # room for the labels and the legend
    return NamedFigure(
        "calibration-residuals",
        "Residuals (RMS and largest, in the image plane and along the distance sensor's beam) on the fitted "
        "and the held-out configurations, and the relative error of held-out pairs with its floor, before "
        "and after calibration (log scale).",
        fig,
    )


def calibration_histogram_figure(r: CalibrationResults) -> NamedFigure | None:
    """Each observation's residual as histograms: the image residual after calibration (fitted and held
    out), the sensor's (signed) after calibration, and the image residual of the nominal model. None
    when the results do not list them (written before they were recorded)."""
    c = r.calibration
    cv = c.cross_validation
    fitted_after, fitted_before = c.residuals.get("after"), c.residuals.get("before")
    held_after = cv.after if cv is not None else None
    held_before = cv.before if cv is not None else None
    if fitted_after is None or not fitted_after.xy_um:
        return None
    panels: list[tuple[str, str, list[tuple[str, list[float], str]]]] = [
        (
            "Image residual, calibrated model",
            "in-plane distance (µm)",
            [
                ("fitted", fitted_after.xy_um, AFTER_C),
                ("held out", (held_after.xy_um or []) if held_after else [], POINT_C),
            ],
        )
    ]
    if fitted_after.z_um:
        panels.append(
            (
                "Sensor residual, calibrated model",
                "measured - predicted (µm)",
                [
                    ("fitted", fitted_after.z_um, AFTER_C),
                    ("held out", (held_after.z_um or []) if held_after else [], POINT_C),
                ],
            )
        )
    if fitted_before is not None and fitted_before.xy_um:
        panels.append(
            (
                "Image residual, nominal model",
                "in-plane distance (µm)",
                [
                    ("fitted", fitted_before.xy_um, BEFORE_C),
                    ("held out", (held_before.xy_um or []) if held_before else [], FLOOR_C),
                ],
            )
        )
    fig = _figure(3.6 * len(panels), 3.4)
    axes = np.atleast_1d(fig.subplots(1, len(panels)))
    for ax, (title, xlabel, sets) in zip(axes, panels, strict=True):
        values = np.concatenate([np.asarray(v, dtype=float) for _, v, _ in sets if v])
        bins = np.histogram_bin_edges(values[np.isfinite(values)], bins="auto")
        for label, v, colour in sets:
            if not v:
                continue
            arr = np.asarray(v, dtype=float)
            _, _, patches = ax.hist(
                arr, bins=bins, histtype="step", lw=1.4, color=colour, label=f"{label} (n={arr.size})"
            )
            for patch in patches:
                patch.set_gid(
                    f"hist-{title.split(',')[0].lower().replace(' ', '-')}-{label.replace(' ', '-')}"
                )
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("observations")
        ax.legend(fontsize=8, loc="upper right")
    return NamedFigure(
        "calibration-residual-histograms",
        "Each observation's residual: the image residual (in-plane distance at the focal plane) and the "
        "distance sensor's residual with the calibrated model, on the fitted and the held-out "
        "configurations, and the image residual with the nominal model. A lone bar far out is an outlier "
        "to look at (the fit has no robust loss).",
        fig,
    )


#: (group, unit) panels of the parameter figure, in order.
_PANELS = (
    ("DH", "mm"),
    ("DH", "deg"),
    ("tool", "mm"),
    ("tool", "deg"),
    ("artifacts", "mm"),
    ("artifacts", "deg"),
)


def calibration_parameters_figure(r: CalibrationResults) -> NamedFigure:
    """Estimate - nominal with the 95 % interval per parameter, one panel per group and unit; structural
    parameters (kept at nominal) and those this pose set does not determine drawn as open markers at 0."""
    panels: list[tuple[str, str, list[CalibrationParameter]]] = []
    for group, unit in _PANELS:
        ps = [p for p in r.parameters if parameter_group(p.name) == group and p.unit == unit]
        if ps:
            panels.append((group, unit, ps))
    others = [p for p in r.parameters if (parameter_group(p.name), p.unit) not in _PANELS]
    if others:
        panels.append(("other", "", others))
    rows = math.ceil(len(panels) / 2) if panels else 1
    heights = [max(len(ps) for _, _, ps in panels[2 * i : 2 * i + 2]) for i in range(rows)] if panels else [1]
    fig = _figure(9.6, 1.0 + 0.2 * sum(heights) + 0.6 * rows)
    grid = fig.add_gridspec(rows, 2, height_ratios=[h + 3 for h in heights])
    for k, (group, unit, ps) in enumerate(panels):
        ax = fig.add_subplot(grid[k // 2, k % 2])
        y = np.arange(len(ps))[::-1]
        err = np.array([p.estimate - p.nominal for p in ps])
        fitted = np.array([p.identified and p.interval is not None for p in ps])
        if fitted.any():
            lo = np.array([p.interval[0] - p.nominal if p.interval else 0.0 for p in ps])
            hi = np.array([p.interval[1] - p.nominal if p.interval else 0.0 for p in ps])
            bars = ax.errorbar(
                err[fitted],
                y[fitted],
                xerr=np.vstack([err[fitted] - lo[fitted], hi[fitted] - err[fitted]]).clip(min=0),
                fmt="o",
                color=POINT_C,
                ecolor=POINT_C,
                ms=3.5,
                capsize=2.5,
                lw=1.0,
            )
            bars[0].set_gid(f"estimates-{group}-{unit}")
        structural = np.array([p.structural for p in ps])
        if structural.any():
            ax.plot(err[structural], y[structural], "x", color=STRUCT_C, ms=6, mew=1.5)
        others_m = ~fitted & ~structural
        if others_m.any():
            ax.plot(err[others_m], y[others_m], "s", mfc="none", mec=FLOOR_C, ms=5)
        ax.axvline(0.0, color=TABLE_C, lw=0.6)
        ax.set_yticks(y, [p.name for p in ps], fontsize=7)
        ax.set_ylim(-0.7, len(ps) - 0.3)
        ax.grid(True, axis="x", lw=0.3, alpha=0.5)
        ax.tick_params(axis="x", labelsize=7)
        ax.set_xlabel(f"estimate − nominal ({unit})" if unit else "estimate − nominal", fontsize=8)
        ax.set_title(f"{group} ({unit})" if unit else group, fontsize=9)
    handles = [
        Line2D([], [], ls="-", marker="o", color=POINT_C, ms=3.5, lw=1.0),
        Line2D([], [], ls="", marker="x", color=STRUCT_C, ms=6, mew=1.5),
        Line2D([], [], ls="", marker="s", mfc="none", mec=FLOOR_C, ms=5),
    ]
    labels = [
        "estimate with 95 % interval",
        "structural: not identifiable (nominal)",
        "not determined by this pose set",
    ]
    fig.legend(handles, labels, loc="outside lower center", ncols=3, fontsize=8, frameon=False)
    fig.suptitle(f"Parameter estimates: {r.identified_count} identified of {len(r.parameters)}", fontsize=11)
    return NamedFigure(
        "calibration-parameters",
        "Each parameter's estimate minus nominal with its 95 % interval, grouped DH / tool / artifacts "
        "and by unit; crosses: structural parameters, kept at nominal.",
        fig,
    )


def singular_values_figure(r: CalibrationResults) -> NamedFigure:
    """The singular values of the column-scaled Jacobian (all parameters), descending, on a log scale, with
    the rcond line: values below it are directions the data do not determine."""
    i = r.calibration.identifiability
    s = np.sort(np.asarray(i.singular_values, dtype=np.float64))[::-1]
    top = float(s[0]) if len(s) and s[0] > 0 else 1.0
    # exact zeros cannot be drawn on a log scale: place them at the axis's bottom, marked
    positive = s[s > 0]
    floor = float(positive.min()) / 10.0 if len(positive) else top * 1e-12
    shown = np.where(s > 0, s, floor)
    k = np.arange(1, len(s) + 1)
    fig = _figure(6.4, 4.0)
    ax = fig.add_subplot()
    cut = i.rcond * top
    above = s >= cut
    ax.semilogy(k, shown, "-", color=LBAR_C, lw=0.6)
    (hi,) = ax.semilogy(
        k[above], shown[above], "o", color=POINT_C, ms=4, label=f"{int(above.sum())} above rcond"
    )
    hi.set_gid("singular-values-above")
    (lo,) = ax.semilogy(
        k[~above],
        shown[~above],
        "o",
        mfc="none",
        mec=ERROR_C,
        ms=5,
        label=f"{int((~above).sum())} below rcond",
    )
    lo.set_gid("singular-values-below")
    line = ax.axhline(cut, color=ERROR_C, ls="--", lw=1.0, label=f"rcond × largest ({i.rcond:.0e})")
    line.set_gid("rcond-line")
    ax.set_xlabel("index (descending)")
    ax.set_ylabel("singular value (unit-norm columns)")
    ax.grid(True, which="both", lw=0.3, alpha=0.5)
    ax.legend(fontsize=8, loc="lower left")
    ax.set_title(
        f"Singular values of the scaled Jacobian (all {len(s)} parameters)\nnull dimension "
        f"{i.null_dimension}, condition number of the identified set {r.condition_number:.3g}",
        fontsize=9,
    )
    return NamedFigure(
        "calibration-singular-values",
        "Singular value spectrum of the column-scaled Jacobian of all parameters (log scale) with the rcond "
        "line; the values below it are the structural directions and what this pose set does not determine.",
        fig,
    )


def results_figures(r: object) -> list[NamedFigure]:
    """Every figure for a session's parsed results."""
    if isinstance(r, ValidationResults):
        if not r.positions:
            return []
        raw = validation_figure(r, fit="raw")
        return [raw] if r.affine is None else [raw, validation_figure(r, fit="parallelogram")]
    if isinstance(r, RepeatabilityResults):
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
    if isinstance(r, SweepResults):
        return [sweep_figure(r)] if r.trials else []
    if isinstance(r, CalibrationResults):
        out = [calibration_residuals_figure(r)]
        histograms = calibration_histogram_figure(r)
        if histograms is not None:
            out.append(histograms)
        if r.parameters:
            out.append(calibration_parameters_figure(r))
        if r.calibration.identifiability.singular_values:
            out.append(singular_values_figure(r))
        return out
    return []
