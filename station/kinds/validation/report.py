"""How a ``validation`` session is reported: the seed's validation error table and the positions
(Figures 14-15's numbers), and Figures 14-15 themselves."""

from __future__ import annotations

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.lines import Line2D
from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

from station.kinds.validation.results import ValidationResults
from station.reporting._figure import (
    ERROR_C,
    TABLE_C,
    NamedFigure,
    fmt_magnification,
    magnification,
    new_figure,
    nice_floor,
)
from station.reporting._session import Session
from station.reporting._table import (
    Table,
    failures_table,
    make_table,
)


def validation_tables(r: ValidationResults, session_id: str) -> dict[str, Table]:
    """The validation error table (seed Figures 14-15) and, per position, the displacements."""
    fits = [
        ("raw (rigid)", r.rigid),
        ("scale (similarity)", r.similarity),
        *([("parallelogram (affine)", r.affine)] if r.affine is not None else []),
    ]
    rows = [
        [
            name,
            f"{f.mean_um:.4f}",
            f"{f.max_um:.4f}",
            "" if f.rms_um is None else f"{f.rms_um:.4f}",
            "" if f.scale is None else f"{f.scale:.6f}",
        ]
        for name, f in fits
    ]
    if r.artifact == "ruler":
        u = "" if r.scale_u is None else f", u = {r.scale_u:.6f}"
        width = (
            "a ruler on the table: each position read absolutely from the ruler's certified pitch; the "
            f"scale compares the micrometers with it{u}"
        )
    elif r.groove_width_mm is None:
        width = "no groove width from the scale fit (the image did not follow the table)"
    else:
        width = f"groove width from the scale fit: {r.groove_width_mm:.5f} mm"
    if r.groove_width_u_mm is not None:
        width += f", u = {r.groove_width_u_mm:.5f} mm"
    width += f" (similarity scale {r.scale:.6f}"
    if r.groove_width_used_mm is not None:
        width += f"; images measured with {r.groove_width_used_mm:.5f} mm"
    notes = [
        "displacement errors after each best fit of commanded to measured positions, in um",
        width + ")",
    ]
    if r.approach is not None:
        notes.append(f"approach: {r.approach}")
    if r.affine is None:
        notes.append("no parallelogram fit: the positions measured lie on a line (the session stopped early)")
    if r.partial:
        notes.append(f"partial: {r.n_positions} of the planned positions measured")
    if r.scale_calibration is not None:
        c = r.scale_calibration
        if c.session_id is None:
            origin = ""
        elif str(c.session_id) == session_id:
            origin = " (estimated by this session)"
        else:
            origin = f" (from session {c.session_id})"
        notes.append(
            f"scale calibration: groove width {c.groove_width_mm:.5f} mm, u = {c.u_mm:.5f} mm{origin}"
        )
    out = {
        "validation": make_table(
            "Validation errors", ("fit", "mean_um", "max_um", "rms_um", "scale"), rows, *notes
        )
    }
    if r.positions:
        prow = [
            [
                str(p.index),
                f"{p.commanded_um[0]:.4f}",
                f"{p.commanded_um[1]:.4f}",
                f"{p.measured_um[0]:.4f}",
                f"{p.measured_um[1]:.4f}",
                f"{_norm(p.error_um):.4f}",
                "" if p.error_parallelogram_um is None else f"{_norm(p.error_parallelogram_um):.4f}",
            ]
            for p in r.positions
        ]
        out["positions"] = make_table(
            "Positions",
            ("index", "cmd_x_um", "cmd_y_um", "meas_x_um", "meas_y_um", "err_raw_um", "err_par_um"),
            prow,
            "commanded: table displacements; measured: image displacements (artifact axes); "
            "err_raw / err_par: |error| after the rigid / parallelogram fit",
        )
    if r.failures:
        out["failures"] = failures_table(r.failures)
    return out


def _norm(v: tuple[float, float]) -> float:
    return float((v[0] ** 2 + v[1] ** 2) ** 0.5)


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

    fig = new_figure(6.4, 6.4)
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
    magnified = f"error lines ×{fmt_magnification(mag)}"
    ax.set_title(f"{title}\nmean {mean:.4f} µm, max {mx:.4f} µm; {magnified}", fontsize=10)
    handles = [
        Line2D([], [], ls="-", marker="o", mfc="white", mec=TABLE_C, color=TABLE_C, lw=0.6, ms=5),
        Line2D([], [], ls="-", marker=".", color=ERROR_C, lw=1.2, ms=5),
    ]
    labels = [f"table positions ({label})", f"measured, error ×{fmt_magnification(mag)}"]
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
        f"error lines magnified ×{fmt_magnification(mag)}.",
        fig,
    )


def tables(r: ValidationResults, s: Session) -> dict[str, Table]:
    """The kind's report tables (``Kind.tables``)."""
    return validation_tables(r, s.id)


def figures(r: ValidationResults) -> list[NamedFigure]:
    """Figures 14 and 15 (the latter with an affine fit), when positions were measured."""
    if not r.positions:
        return []
    raw = validation_figure(r, fit="raw")
    return [raw] if r.affine is None else [raw, validation_figure(r, fit="parallelogram")]
