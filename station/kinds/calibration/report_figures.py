"""How a ``calibration`` session is drawn: the residuals and the relative error before / after (log
scale), the residuals' histograms, each parameter's estimate - nominal with its 95 % interval, and the
singular value spectrum of the scaled Jacobian with the rcond line."""

from __future__ import annotations

import math

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D

from station.calibration import ResidualSummary as CalibrationResiduals
from station.kinds.calibration.report_tables import parameter_group
from station.kinds.calibration.results import CalibrationParameter, CalibrationResults
from station.reporting._figure import (
    AFTER_C,
    BEFORE_C,
    ERROR_C,
    FLOOR_C,
    LBAR_C,
    POINT_C,
    STRUCT_C,
    TABLE_C,
    NamedFigure,
    new_figure,
)


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
    fig = new_figure(9.6, 4.2)
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
    fig = new_figure(3.6 * len(panels), 3.4)
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
    fig = new_figure(9.6, 1.0 + 0.2 * sum(heights) + 0.6 * rows)
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
    fig = new_figure(6.4, 4.0)
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


def figures(r: CalibrationResults) -> list[NamedFigure]:
    """The residuals, their histograms (when recorded), the parameters and the singular values."""
    out = [calibration_residuals_figure(r)]
    histograms = calibration_histogram_figure(r)
    if histograms is not None:
        out.append(histograms)
    if r.parameters:
        out.append(calibration_parameters_figure(r))
    if r.calibration.identifiability.singular_values:
        out.append(singular_values_figure(r))
    return out
