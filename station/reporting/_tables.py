"""The report's tables, each built once and rendered as text (the CLI) or HTML (the report).

The seed's tables: the validation error table (section 4, Figures 14-15: raw, scale and parallelogram
errors), Table 1 (the parameter study; its column logic is shared with ``station sweep`` through
``station.report.sweep_table``) and Table 2 (repeatability, eq. 13: RP = l-bar + 3 S_l). A calibration
session's: the relative error before / after / floor, the residuals, the parameter estimates with their
95 % intervals, and the identifiability analysis (see ``station/calibration/CALIBRATION.md``).
"""

from __future__ import annotations

import html
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from station.calibration import ResidualSummary as CalibrationResiduals
from station.kinds.calibration.results import CalibrationParameter, CalibrationResults, Deficiency
from station.kinds.repeatability.results import FailedTest, RepeatabilityResults, RepeatabilityTest
from station.kinds.sweep.results import SweepResults
from station.kinds.validation.results import ValidationResults
from station.plans._results import Check
from station.report import SweepRow, is_seed_table_1, seed_table_1, sweep_note, sweep_table, table
from station.reporting._model import Session, format_date, format_value


@dataclass(frozen=True)
class Table:
    """A titled table of text cells; ``marked`` rows (e.g. the best trial) are emphasised in HTML."""

    title: str
    headers: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    notes: tuple[str, ...] = ()
    marked: frozenset[int] = frozenset()

    def text(self) -> str:
        parts = [self.title, table(self.headers, self.rows)]
        if self.notes:
            parts.append("\n".join(self.notes))
        return "\n".join(parts)

    def html(self) -> str:
        e = html.escape
        head = "".join(f"<th>{e(h)}</th>" for h in self.headers)
        body = []
        for i, row in enumerate(self.rows):
            cls = ' class="marked"' if i in self.marked else ""
            cells = "".join(f"<td>{e(c)}</td>" for c in row)
            body.append(f"<tr{cls}>{cells}</tr>")
        notes = "".join(f'<p class="note">{e(n)}</p>' for n in self.notes)
        return (
            f"<table><caption>{e(self.title)}</caption><thead><tr>{head}</tr></thead>"
            f"<tbody>{''.join(body)}</tbody></table>{notes}"
        )


def _make(title: str, headers: Sequence[str], rows: Sequence[Sequence[str]], *notes: str) -> Table:
    return Table(title, tuple(headers), tuple(tuple(r) for r in rows), tuple(n for n in notes if n))


def session_table(s: Session) -> Table:
    """Who, what, when: id, kind, state, date, software, source session and error."""
    rows = [
        ("id", s.id),
        ("kind", s.kind),
        ("state", s.state),
        ("created", format_date(s.created_at)),
        ("software", ", ".join(f"{k} {format_value(v)}" for k, v in s.software.items()) or "not recorded"),
    ]
    if s.source_session is not None:
        rows.append(("source session", s.source_session))
    if s.error is not None:
        rows.append(("error", s.error))
    return _make("Session", ("field", "value"), rows)


def parameters_table(s: Session) -> Table:
    """One row per parameter; groups (the plan's, the measurement's) flattened as ``group.name``."""
    rows = []
    for k, v in s.params.items():
        if isinstance(v, dict) and v:
            rows += [(f"{k}.{name}", format_value(value)) for name, value in v.items()]
        else:
            rows.append((str(k), format_value(v)))
    return _make("Parameters", ("parameter", "value"), rows or [("(none recorded)", "")])


def devices_table(s: Session) -> Table:
    """One row per device; one column per identity field (model, serial or port, firmware, ...)."""
    fields: list[str] = []
    for ident in s.identities.values():
        if isinstance(ident, dict):
            fields += [str(k) for k in ident if str(k) not in fields]
    rows = []
    for name, ident in s.identities.items():
        if isinstance(ident, dict):
            rows.append([str(name), *(format_value(ident.get(f, "")) for f in fields)])
        else:
            rows.append([str(name), format_value(ident), *([""] * (len(fields) - 1))])
    if not rows:
        return _make("Devices", ("device", "identity"), [("(none recorded)", "")])
    return _make("Devices", ("device", *(fields or ["identity"])), rows)


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
    if r.groove_width_mm is None:
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
        "validation": _make(
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
        out["positions"] = _make(
            "Positions",
            ("index", "cmd_x_um", "cmd_y_um", "meas_x_um", "meas_y_um", "err_raw_um", "err_par_um"),
            prow,
            "commanded: table displacements; measured: image displacements (artifact axes); "
            "err_raw / err_par: |error| after the rigid / parallelogram fit",
        )
    if r.failures:
        out["failures"] = failures_table(r.failures)
    return out


def failures_table(failures: Sequence[Mapping[str, Any]], tests: Sequence[str] | None = None) -> Table:
    """Captures whose measurement failed: where (test, step, frame, capture) and why."""
    rows = []
    for i, f in enumerate(failures):
        error = format_value(f.get("error") or "not measured") + (f" ({f['code']})" if f.get("code") else "")
        where = [format_value(f.get(k)) for k in ("step_index", "frame_index", "capture_id")]
        rows.append([*([tests[i]] if tests is not None else []), *where, error])
    headers = [*(["test"] if tests is not None else []), "step", "frame", "capture", "error"]
    return _make("Captures not measured", headers, rows, "kept in the record; left out of the results")


def _norm(v: tuple[float, float]) -> float:
    return float((v[0] ** 2 + v[1] ** 2) ** 0.5)


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
    out = {"repeatability": _make("Repeatability (Table 2)", headers, rows, *notes)}
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


def checks_table(checks: Sequence[Check]) -> Table:
    """The gates' verdicts: a failed ``fail`` check failed the session, a failed ``warn`` check is shown."""
    rows = []
    for c in checks:
        verdict = "passed" if c.passed else ("FAILED" if c.severity == "fail" else "warning")
        if isinstance(c.limit, tuple):
            limit = f"[{c.limit[0]:.6g}, {c.limit[1]:.6g}]"
        else:
            limit = "" if c.limit is None else f"{c.limit:.6g}"
        value = "-" if c.value is None else f"{c.value:.6g}"
        rows.append([c.name, verdict, value, limit, c.severity, c.message])
    return _make(
        "Checks",
        ("check", "verdict", "value", "limit", "severity", "message"),
        rows,
        "each result checked against what is physically possible; a failed 'fail' check fails the session",
    )


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
    out = {"sweep": Table("Parameter study (Table 1)", tuple(headers), _tuples(rows), tuple(notes), marked)}
    if seed_layout:
        out["seed_table_1"] = _make("The seed's Table 1", *seed_table_1())
    return out


def _tuples(rows: Sequence[Sequence[str]]) -> tuple[tuple[str, ...], ...]:
    return tuple(tuple(r) for r in rows)


#: The issue's targets for the relative error: after at least 10x below before, within 2x of the floor.
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
    """Before / after / floor (um) and the two ratios the issue's targets are stated in."""
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
    return _make("Relative positioning error", ("quantity", "value_um", "target"), rows, *notes)


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
    return _make("Residuals before and after", headers, rows, *notes)


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
    return _make(
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
    out = {"identifiability": _make("Identifiability", ("quantity", "value"), rows, *notes)}
    srows = [
        [
            d.name,
            trades_with(d),
            "-" if d.residual is None else f"{d.residual:.1e}",
            d.reason,
        ]
        for d in i.structural
    ]
    out["structural"] = _make(
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
        out["deficiencies"] = _make(
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
        "residuals": calibration_residuals_table(r),
        "estimates": estimates_table(r),
        **identifiability_tables(r),
    }


def results_tables(s: Session) -> dict[str, Table]:
    """The tables of a session's results (none when it has none), their checks first."""
    checks: list[Check] = getattr(s.results, "checks", [])
    tables = _kind_tables(s)
    return {"checks": checks_table(checks), **tables} if checks else tables


def _kind_tables(s: Session) -> dict[str, Table]:
    r = s.results
    if isinstance(r, ValidationResults):
        return validation_tables(r, s.id)
    if isinstance(r, RepeatabilityResults):
        return repeatability_tables(r)
    if isinstance(r, CalibrationResults):
        return calibration_tables(r)
    if isinstance(r, SweepResults):
        measure = s.params.get("measure")
        mode = measure.get("mode") if isinstance(measure, Mapping) else s.params.get("mode")
        return sweep_tables(r, None if mode is None else str(mode))
    return {}


def all_tables(s: Session) -> dict[str, Table]:
    """Session facts, devices, parameters, then the results' tables."""
    return {
        "session": session_table(s),
        "devices": devices_table(s),
        "parameters": parameters_table(s),
        **results_tables(s),
    }
