"""How a ``calibration`` session is tabled: the relative error before / after / floor, the residuals,
the parameter estimates with their 95 % intervals and the identifiability analysis (see
``station/calibration/CALIBRATION.md``)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from station.calibration import ResidualSummary as CalibrationResiduals
from station.kinds.calibration.results import CalibrationParameter, CalibrationResults, Deficiency
from station.reporting._session import Session
from station.reporting._table import (
    Table,
    make_table,
)

#: The calibration's targets for the relative error: after at least 10x below before, within 2x of the floor.
BEFORE_AFTER_TARGET, AFTER_FLOOR_TARGET = 10.0, 2.0


def _um(v: float | None, digits: int = 1) -> str:
    return "-" if v is None else f"{v:.{digits}f}"


def _ratio(num: float | None, den: float | None) -> float | None:
    if num is None or den is None or den <= 0 or not math.isfinite(num / den):
        return None
    return num / den


def _verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def relative_error_table(r: CalibrationResults) -> Table:
    """Before / after / floor (um) and the two ratios the targets are stated in."""
    e = r.relative_error_um
    gain, excess = _ratio(e.before, e.after), _ratio(e.after, e.floor)
    rows = [
        ("before (nominal model)", _um(e.before), ""),
        ("after (calibrated model)", _um(e.after), ""),
        ("floor (repeatability and noise)", _um(e.floor), ""),
        (
            "before / after",
            "-" if gain is None else f"{gain:.1f}x",
            f">= {BEFORE_AFTER_TARGET:g}x: "
            + ("-" if gain is None else _verdict(gain >= BEFORE_AFTER_TARGET)),
        ),
        (
            "after / floor",
            "-" if excess is None else f"{excess:.2f}x",
            f"<= {AFTER_FLOOR_TARGET:g}x: "
            + ("-" if excess is None else _verdict(excess <= AFTER_FLOOR_TARGET)),
        ),
    ]
    held = r.held_out_configurations
    notes = [
        "mean in-plane distance (um) between the crossings two held-out configurations measure of one "
        f"placement; held-out configurations: {', '.join(map(str, held)) if held else 'none'}",
    ]
    if r.floor_source:
        notes.append(f"floor: {r.floor_source}")
    missing = [k for k in ("before", "after", "floor") if getattr(e, k) is None]
    if missing:
        notes.append(f"not computed: {', '.join(missing)} (too few held-out pairs or no return captures)")
    return make_table("Relative positioning error", ("quantity", "value_um", "target"), rows, *notes)


def ruler_tables(r: CalibrationResults) -> dict[str, Table]:
    """With rulers: the error along them (before / after / floor) and the magnification they gave."""
    a, m = r.absolute_error_um, r.magnification
    if a is None:
        return {}
    gain, excess = _ratio(a.before, a.after), _ratio(a.after, a.floor)
    rows = [
        ("before (nominal model)", _um(a.before, 2)),
        ("after (calibrated model)", _um(a.after, 2)),
        ("floor (repeatability and noise)", _um(a.floor, 2)),
        ("before / after", "-" if gain is None else f"{gain:.1f}x"),
        ("after / floor", "-" if excess is None else f"{excess:.2f}x"),
    ]
    notes = [f"{r.absolute_pairs or 0} held-out pairs of frames of {r.ruler_frames or 0} ruler frames"]
    if m is not None:
        interval = "" if m.interval is None else f", 95 % [{m.interval[0]:.4f}, {m.interval[1]:.4f}]"
        notes.append(
            f"magnification {m.px_per_mm:.4f} px/mm{interval} (nominal {m.nominal_px_per_mm:.4f}: "
            f"{m.relative_to_nominal * 100:+.3f} %), from the rulers' certified pitch; sensor mount "
            f"z {m.sensor_z_mm:+.4f} mm"
        )
    return {"absolute_error": make_table("Error along the rulers", ("quantity", "value_um"), rows, *notes)}


def measures_table(r: CalibrationResults) -> dict[str, Table]:
    """What each figure measures and over which region (``results.measures``: data, not prose here)."""
    if not r.measures:
        return {}
    rows = [(k, v.meaning, v.region) for k, v in r.measures.items()]
    return {"measures": make_table("What each figure measures", ("figure", "meaning", "region"), rows)}


def _residual_row(
    data: str, model: str, s: CalibrationResiduals | None, before: CalibrationResiduals | None
) -> list[str]:
    if s is None:
        return [data, model, "0", "-", "-", "-", "-", "-"]
    gain = "" if before is None or s is before else _times(before.rms_xy_mm, s.rms_xy_mm)
    return [
        data,
        model,
        str(s.n),
        f"{s.rms_xy_mm * 1000.0:.2f}",
        f"{s.max_xy_mm * 1000.0:.2f}",
        "-" if s.rms_z_mm is None else f"{s.rms_z_mm * 1000.0:.2f}",
        "-" if s.max_z_mm is None else f"{s.max_z_mm * 1000.0:.2f}",
        gain,
    ]


def _times(before: float, after: float) -> str:
    r = _ratio(before, after)
    return "" if r is None else f"{r:.1f}x"


def calibration_residuals_table(r: CalibrationResults) -> Table:
    """RMS and largest residuals (um) in the image plane and along the sensor's beam, before and after,
    on the fitted observations and on the held-out configurations."""
    c = r.calibration
    fit_b, fit_a = c.residuals.get("before"), c.residuals.get("after")
    rows = [_residual_row("fitted", "before", fit_b, None), _residual_row("fitted", "after", fit_a, fit_b)]
    cv = c.cross_validation
    if cv is not None and (cv.before is not None or cv.after is not None):
        rows += [
            _residual_row("held out", "before", cv.before, None),
            _residual_row("held out", "after", cv.after, cv.before),
        ]
    notes = [
        "xy: the crossing's image position at the focal plane; z: the distance sensor's reading; "
        "before: nominal model (artifacts fitted alone), after: calibrated model; rms_xy over the "
        "points' in-plane distances; gain: rms_xy before / after"
    ]
    if c.fit is not None:
        f = c.fit
        s2 = "" if f.s2 is None else f", variance factor s2 = {f.s2:.3g}"
        notes.append(
            f"fit: {f.method}, {f.evaluations} evaluations, status {f.status} ({f.message}); "
            f"{f.observations} observations, {f.residuals} residuals, {f.dof} degrees of freedom{s2}"
        )
        if f.loss != "linear":
            scale = "" if f.f_scale is None else f" (scale {f.f_scale:g} sigmas)"
            notes.append(
                f"robust loss {f.loss}{scale}: {f.downweighted} residuals weigh less than half; intervals"
                " from s2 (J^T W J)^-1 with the final weights"
            )
    if c.sigmas_mm:
        sig = ", ".join(f"{k} {v * 1000.0:g} um" for k, v in c.sigmas_mm.items())
        notes.append(f"weights: measurement sigmas {sig}")
    headers = ("data", "model", "n", "rms_xy_um", "max_xy_um", "rms_z_um", "max_z_um", "gain")
    return make_table("Residuals before and after", headers, rows, *notes)


def parameter_group(name: str) -> str:
    """``DH`` (the arm's table, joint zeros and Hayati's beta), ``tool`` or ``artifacts``."""
    if name.startswith("tool"):
        return "tool"
    if name.startswith("artifact"):
        return "artifacts"
    return "DH"


def _structural_reasons(r: CalibrationResults) -> dict[str, Deficiency]:
    """Structural deficiencies by the names parameters are listed under (``d3`` is listed as ``d2-d3``)."""
    out: dict[str, Deficiency] = {}
    for d in r.calibration.identifiability.structural:
        out[d.name] = d
    structural = {p.name for p in r.parameters if p.structural}
    for d in r.calibration.identifiability.structural:  # a combination's name: 'd2-d3' stands for d3
        for term in _split_terms(d.name):
            if term in structural and term not in out:
                out[term] = d
    return out


def _split_terms(name: str) -> set[str]:
    return {t for t in name.replace("+", " ").replace("-", " ").split() if t}


def trades_with(d: Deficiency, *, most: int = 5) -> str:
    """A deficiency's combination as text, largest coefficients first: ``-1 artifact0_z -1 artifact1_z``;
    beyond ``most`` terms, how many more."""
    terms = sorted(d.combination.items(), key=lambda kv: (-abs(kv[1]), kv[0]))
    text = " ".join(f"{k:+.3g} {n}" for n, k in terms[:most]) or "(no effect on the data)"
    return text + (f" (+{len(terms) - most} more)" if len(terms) > most else "")


def _dig(unit: str) -> int:
    return 5 if unit == "deg" else 4


def _status(p: CalibrationParameter, reasons: Mapping[str, Deficiency], dropped: set[str]) -> str:
    if p.structural:
        d = reasons.get(p.name)
        return "not identifiable (structural)" + (f": {d.reason}" if d is not None and d.reason else "")
    if not p.identified:
        return "not identified (this pose set)" if p.name in dropped else "not identified"
    return "identified"


def estimates_table(r: CalibrationResults) -> Table:
    """Per parameter: nominal, estimate - nominal, the 95 % interval (as errors from nominal) and sigma."""
    reasons = _structural_reasons(r)
    dropped = {d.name for d in r.calibration.identifiability.dropped}
    rows = []
    for group in ("DH", "tool", "artifacts"):
        for p in (p for p in r.parameters if parameter_group(p.name) == group):
            n = _dig(p.unit)
            if p.interval is not None:
                lo, hi = (v - p.nominal for v in p.interval)
                interval = f"{lo:+.{n}f} .. {hi:+.{n}f}"
            else:
                interval = "-"
            rows.append(
                [
                    p.name,
                    group,
                    p.unit,
                    f"{p.nominal:.{n}f}",
                    f"{p.estimate - p.nominal:+.{n}f}",
                    interval,
                    "-" if p.sigma is None else f"{p.sigma:.{n}f}",
                    _status(p, reasons, dropped),
                ]
            )
    headers = ("parameter", "group", "unit", "nominal", "estimate-nominal", "95%_interval-nominal", "sigma")
    return make_table(
        "Parameter estimates",
        (*headers, "status"),
        rows,
        f"{r.identified_count} identified of {len(r.parameters)}; 95 % intervals from the covariance "
        "s2 (J^T J)^-1 and Student's t, written as errors from nominal like the estimate",
        "DH: modified Denavit-Hartenberg row i (alpha{i-1}, a{i-1}, d{i}, theta{i}_offset) and Hayati's "
        "beta2; d2+d3: axes 2 and 3 are parallel, only the sum is identifiable; structural ones stay at "
        "nominal",
    )


def _singular_summary(values: Sequence[float], rcond: float) -> str:
    if not values:
        return "not recorded"
    s = sorted(values, reverse=True)
    top = s[0]
    below = sum(1 for v in s if v < rcond * top)
    return (
        f"{len(s)} values, largest {top:.3g}, smallest {s[-1]:.3g}; {below} below rcond x largest "
        f"({rcond * top:.3g})"
    )


def identifiability_tables(r: CalibrationResults) -> dict[str, Table]:
    """The identifiability summary, the structural list with what each trades with, and the pose set's
    own deficiencies when it has any."""
    i = r.calibration.identifiability
    rows = [
        ("condition number (identified set, unit columns)", f"{r.condition_number:.4g}"),
        ("identified parameters", f"{r.identified_count} of {len(r.parameters)}"),
        ("null dimension (all parameters)", str(i.null_dimension)),
        ("structural deficiencies", str(len(i.structural))),
        (
            "structural list verified",
            "-" if i.structural_verified is None else ("yes" if i.structural_verified else "NO"),
        ),
        ("singular values (scaled Jacobian)", _singular_summary(i.singular_values, i.rcond)),
        ("rcond", f"{i.rcond:.3g}"),
        ("deficient in this pose set", ", ".join(i.deficient) if i.deficient else "none"),
    ]
    notes = [
        "SVD of the column-scaled Jacobian of all parameters at nominal; structural: what no pose set "
        "identifies on this arm (they stay at nominal); deficient: directions this pose set leaves "
        "undetermined (below rcond), which a richer pose set removes"
    ]
    if r.configurations is not None or r.observations is not None:
        what = [f"{r.observations} observations" if r.observations is not None else ""]
        if r.configurations is not None:
            planned = (
                f" of {r.planned_configurations} planned" if r.planned_configurations is not None else ""
            )
            what.append(f"{r.configurations} configurations{planned}")
        if r.placements:
            what.append(f"placements {', '.join(map(str, r.placements))}")
        if r.left_out:
            what.append(f"{len(r.left_out)} captures left out")
        notes.append("data: " + ", ".join(w for w in what if w))
    out = {"identifiability": make_table("Identifiability", ("quantity", "value"), rows, *notes)}
    srows = [
        [
            d.name,
            trades_with(d),
            "-" if d.residual is None else f"{d.residual:.1e}",
            d.reason,
        ]
        for d in i.structural
    ]
    out["structural"] = make_table(
        "Not identifiable on this arm (structural)",
        ("parameter", "trades with", "residual", "why"),
        srows or [("(none)", "", "", "")],
        "trades with: the combination of identified parameters (natural units) whose effect on the data "
        "equals the parameter's; residual: the column's relative distance from it (0: indistinguishable)",
    )
    if i.dropped or i.deficient:
        drows = [
            [d.name, trades_with(d), "-" if d.residual is None else f"{d.residual:.1e}", d.reason]
            for d in i.dropped
        ]
        named = {d.name for d in i.dropped}
        drows += [[n, "(weight in a near-null direction)", "", ""] for n in i.deficient if n not in named]
        out["deficiencies"] = make_table(
            "Not determined by this pose set",
            ("parameter", "trades with", "residual", "note"),
            drows,
            "dropped by subset selection (QR with column pivoting) or implicated in a direction below "
            "rcond; more configurations, turns, IK solutions or placements resolve them",
        )
    return out


def calibration_tables(r: CalibrationResults) -> dict[str, Table]:
    """The relative error, residuals, parameter estimates and the identifiability analysis."""
    return {
        "relative_error": relative_error_table(r),
        **ruler_tables(r),
        **measures_table(r),
        "residuals": calibration_residuals_table(r),
        "estimates": estimates_table(r),
        **identifiability_tables(r),
    }


def tables(r: CalibrationResults, s: Session) -> dict[str, Table]:
    """The kind's report tables (``Kind.tables``)."""
    return calibration_tables(r)
