// Results per session kind, as tables: validation, repeatability (N per test, partial tests marked),
// calibration (relative error before / after / floor, condition number, identified count, parameters),
// sweep (the trials), re-analysis (its kind's). Integers show as integers. Also: the results' gates
// (`checks`), and whether the kind has a CSV table (the API's ?format=csv answers only then).

import { el, gridTable, kvTable, num, um } from "./util.js";

const mm = (v, d = 4) => (typeof v === "number" ? `${num(v, d)} mm` : "—");
const pair = (p, d) => (Array.isArray(p) ? p.map((v) => num(v, d)).join(", ") : "—");

function validation(r) {
  const rows = [
    ["mean error (after the rigid fit)", um(r.mean_um, 3)],
    ["max error (after the rigid fit)", um(r.max_um, 3)],
    ["mean error (parallelogram, affine fit)", um(r.parallelogram_mean_um, 3)],
    ["max error (parallelogram, affine fit)", um(r.parallelogram_max_um, 3)],
    ["scale", num(r.scale, 6)],
    ["groove width", mm(r.groove_width_mm, 5)],
  ];
  if (typeof r.groove_width_u_mm === "number") rows.push(["its standard uncertainty", mm(r.groove_width_u_mm, 5)]);
  if (r.n_positions !== undefined) rows.push(["positions measured", num(r.n_positions)]);
  if (r.approach) rows.push(["approach", r.approach]);
  const out = [kvTable("results-table", rows, "Validation against the X-Y table")];
  if (Array.isArray(r.positions) && r.positions.length) {
    const body = r.positions.map((p, i) => [
      num(p.index ?? i),
      pair(p.commanded_um, 1),
      pair(p.measured_um, 2),
      pair(p.error_um, 3),
    ]);
    out.push(gridTable("positions-table", ["#", "commanded (µm)", "measured (µm)", "error (µm)"], body, "Positions"));
  }
  return out;
}

function repeatability(r, params) {
  const planned = params?.plan?.cycles;
  const tests = Object.entries(r.tests || {});
  const body = tests.map(([name, t]) => {
    if (t.error) return [name, "—", "—", `not computed: ${t.error}`, "—", "—", "—"];
    const n = typeof planned === "number" && (t.partial || t.n_cycles < planned) ? `${num(t.n_cycles)} of ${num(planned)} (partial)` : num(t.n_cycles);
    const ci = Array.isArray(t.rp_ci95_mm) ? `${num(t.rp_ci95_mm[0], 5)} – ${num(t.rp_ci95_mm[1], 5)}` : "—";
    const motion = t.kind === "joint" ? `joint ${num(t.joint)}${typeof t.delta_deg === "number" ? `, ${t.delta_deg > 0 ? "+" : ""}${num(t.delta_deg, 1)}°` : ""}` : `${t.kind}${Array.isArray(t.targets_deg) ? `, ${t.targets_deg.length} targets` : ""}`;
    const headline = name in (r.rp_mm || {}) ? num(t.rp_mm, 5) : `${num(t.rp_mm, 5)} (partial: not in RP)`;
    return [name, motion, n, headline, ci, num(t.l_bar_mm, 5), num(t.s_l_mm, 5)];
  });
  const summary = [["cycles per test", num(r.n_cycles)]];
  if (r.speed_pct !== undefined && r.speed_pct !== null) summary.push(["speed", `${num(r.speed_pct)} %`]);
  if (r.load_kg !== undefined && r.load_kg !== null) summary.push(["load", `${num(r.load_kg)} kg`]);
  return [
    kvTable("results-table", summary, "Pose repeatability (ISO 9283: RP = l̄ + 3 Sₗ)"),
    gridTable("tests-table", ["test", "motion", "N", "RP (mm)", "95 % interval (mm)", "l̄ (mm)", "Sₗ (mm)"], body, "Per test"),
  ];
}

function calibration(r) {
  const e = r.relative_error_um || {};
  const rows = [
    ["relative error before (nominal model)", um(e.before, 2)],
    ["relative error after (calibrated model)", um(e.after, 2)],
    ["relative error floor (the arm's repeatability)", um(e.floor, 2)],
    ["condition number", num(r.condition_number, 1)],
    ["parameters identified", num(r.identified_count)],
  ];
  if (r.floor_source) rows.push(["floor from", r.floor_source]);
  if (Array.isArray(r.unidentifiable)) rows.push(["not identifiable here", r.unidentifiable.join(", ") || "none"]);
  if (r.loss) rows.push(["loss", String(r.loss)]);
  const out = [kvTable("results-table", rows, "Kinematic calibration")];
  if (Array.isArray(r.parameters) && r.parameters.length) {
    const body = r.parameters.map((p) => [
      p.name,
      p.unit,
      num(p.nominal, 4),
      num(p.estimate, 4),
      Array.isArray(p.interval) ? `${num(p.interval[0], 4)} – ${num(p.interval[1], 4)}` : "—",
      num(p.sigma, 4),
      p.identified ? "yes" : p.structural ? "no (structural)" : "no",
    ]);
    const table = gridTable("parameters-table", ["name", "unit", "nominal", "estimate", "95 % interval", "σ", "identified"], body);
    out.push(el("details", {}, el("summary", {}, `Parameters (${r.parameters.length})`), table));
  }
  return out;
}

function sweep(r) {
  const trials = Array.isArray(r.trials) ? r.trials : [];
  const body = trials.map((t) => [
    num(t.trial ?? t.number) + (r.best !== undefined && r.best === (t.trial ?? t.number) ? " (best)" : ""),
    Object.entries(t.overrides || {}).map(([k, v]) => `${k}=${JSON.stringify(v)}`).join(", ") || "defaults",
    um(t.mean_um, 3),
    um(t.max_um, 3),
    um(t.parallelogram_mean_um, 3),
    um(t.parallelogram_max_um, 3),
    t.error || "",
  ]);
  return [
    kvTable("results-table", [["trials", num(trials.length)], ["source session", r.source_session || "—"]], "Parameter study"),
    gridTable("trials-table", ["trial", "parameters", "mean", "max", "parallelogram mean", "parallelogram max", "error"], body),
  ];
}

function generic(r) {
  const rows = Object.entries(r).filter(([, v]) => typeof v !== "object").map(([k, v]) => [k, num(v)]);
  return [kvTable("results-table", rows)];
}

/** The results' tables for a session of `kind` (`params`: the session's recorded parameters). */
export function resultTables(kind, r, params) {
  if (kind === "reanalyse") {
    const inner = r[r.kind] || {};
    const head = kvTable("reanalysis-table", [["re-analysis of", `${r.source_session || "?"} (${r.kind || "?"})`]]);
    return [head, ...(r.kind ? resultTables(r.kind, inner, params) : [])];
  }
  const render = { validation, repeatability, calibration, sweep }[kind] || generic;
  return render(r, params);
}

/** Whether GET /results?format=csv has a table for these results (it answers 409 otherwise). */
export function hasTable(kind, r) {
  if (!r) return false;
  if (kind === "reanalyse") return typeof r.kind === "string" && hasTable(r.kind, r[r.kind]);
  if (kind === "validation") return Array.isArray(r.positions) && r.positions.length > 0;
  if (kind === "repeatability") return Object.values(r.tests || {}).some((t) => Array.isArray(t.points_mm) && t.points_mm.length);
  if (kind === "calibration") return Array.isArray(r.parameters) && r.parameters.length > 0;
  if (kind === "sweep") return Array.isArray(r.trials) && r.trials.length > 0;
  return false;
}

/** The gates (`results.checks`: name, passed, value, limit, severity, message), when the results have them. */
export function checksTable(checks) {
  if (!Array.isArray(checks) || !checks.length) return null;
  const body = checks.map((c) => {
    const verdict = c.passed ? "passed" : c.severity === "warn" ? "warning" : "FAILED";
    return [c.name, verdict, num(c.value), num(c.limit), c.message || ""];
  });
  const box = gridTable("checks-table", ["check", "verdict", "value", "limit", "message"], body, "Checks");
  box.querySelectorAll("tbody tr").forEach((tr, i) => {
    tr.dataset.verdict = checks[i].passed ? "passed" : checks[i].severity === "warn" ? "warn" : "fail";
  });
  return box;
}
