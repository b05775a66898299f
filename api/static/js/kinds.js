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

/** A test's N: "11 of 30 (partial)" when it has fewer cycles than planned (its own RP, never the headline's). */
function cyclesText(t, planned) {
  const n = typeof t.n_cycles === "number" ? t.n_cycles : null;
  if (n === null) return "—";
  return t.partial || (typeof planned === "number" && n < planned) ? `${num(n)} of ${num(planned)} (partial)` : num(n);
}

function repeatability(r, params) {
  const tests = Object.entries(r.tests || {});
  const plannedOf = (t) => t.planned_cycles ?? r.n_cycles ?? params?.plan?.cycles;
  const body = tests.map(([name, t]) => {
    const n = cyclesText(t, plannedOf(t));
    if (t.error) return [name, "—", n, `not computed: ${t.error}`, "—", "—", "—"];
    const ci = Array.isArray(t.rp_ci95_mm) ? `${num(t.rp_ci95_mm[0], 5)} – ${num(t.rp_ci95_mm[1], 5)}` : "—";
    const motion = t.kind === "joint" ? `joint ${num(t.joint)}${typeof t.delta_deg === "number" ? `, ${t.delta_deg > 0 ? "+" : ""}${num(t.delta_deg, 1)}°` : ""}` : `${t.kind}${Array.isArray(t.targets_deg) ? `, ${t.targets_deg.length} targets` : ""}`;
    const headline = name in (r.rp_mm || {}) ? num(t.rp_mm, 5) : `${num(t.rp_mm, 5)} (partial: not in RP)`;
    return [name, motion, n, headline, ci, num(t.l_bar_mm, 5), num(t.s_l_mm, 5)];
  });
  const whole = Object.entries(r.rp_mm || {});
  const partial = tests.filter(([name, t]) => t.partial || !(name in (r.rp_mm || {})));
  const summary = [
    ["RP (whole tests only)", whole.length ? whole.map(([name, v]) => `${name} ${num(v, 5)} mm`).join(", ") : "none: no test has every planned cycle"],
    ["cycles planned per test", num(r.n_cycles)],
  ];
  if (partial.length) {
    summary.push(["partial tests (their own RP, not in the headline)", partial.map(([name, t]) => `${name}: N ${cyclesText(t, plannedOf(t))}`).join("; ")]);
  }
  if (r.speed_pct !== undefined && r.speed_pct !== null) summary.push(["speed", `${num(r.speed_pct)} %`]);
  if (r.load_kg !== undefined && r.load_kg !== null) summary.push(["load", `${num(r.load_kg)} kg`]);
  const grid = gridTable("tests-table", ["test", "motion", "N", "RP (mm)", "95 % interval (mm)", "l̄ (mm)", "Sₗ (mm)"], body, "Per test");
  grid.querySelectorAll("tbody tr").forEach((tr, i) => {
    const [name, t] = tests[i];
    tr.dataset.test = name;
    tr.dataset.partial = String(Boolean(t.partial || !(name in (r.rp_mm || {}))));
  });
  return [kvTable("results-table", summary, "Pose repeatability (ISO 9283: RP = l̄ + 3 Sₗ)"), grid];
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

/** What a resume of a session of `kind` does (README, Sessions): no population ever mixes two runs. */
export function resumeRule(kind) {
  if (kind === "repeatability") {
    return "it reruns the interrupted test from its start (the interrupted attempt's captures stay in the record, never in RP); the tests already done are kept.";
  }
  if (kind === "validation") {
    return "it first captures the last confirmed position again and goes on only if it measures where it did before.";
  }
  if (kind === "calibration") return "it starts again at the interrupted configuration's start.";
  return "it goes on after its last completed step.";
}

const failing = (c) => !c.passed && c.severity !== "warn";

/** The `fail` checks these results did not pass (a session that has any ended failed by its gates). */
export function failedChecks(checks) {
  return Array.isArray(checks) ? checks.filter(failing) : [];
}

function limitText(limit) {
  if (Array.isArray(limit)) return `${num(limit[0], 5)} – ${num(limit[1], 5)}`;
  return num(limit, 5);
}

/** The gates (`results.checks`: name, passed, value, limit, severity, message), when the results have them:
 * each row's verdict in words and in `data-verdict` (`passed`, `warn`, `fail`), failed rows first. */
export function checksTable(checks) {
  if (!Array.isArray(checks) || !checks.length) return null;
  const verdict = (c) => (c.passed ? "passed" : c.severity === "warn" ? "warn" : "fail");
  const order = { fail: 0, warn: 1, passed: 2 };
  const sorted = [...checks].sort((a, b) => order[verdict(a)] - order[verdict(b)]);
  const words = { passed: "passed", warn: "warning", fail: "FAILED" };
  const body = sorted.map((c) => [c.name, words[verdict(c)], num(c.value, 5), limitText(c.limit), c.message || ""]);
  const failed = sorted.filter(failing).length;
  const warned = sorted.filter((c) => verdict(c) === "warn").length;
  const caption = `Checks against what is physically possible: ${failed ? `${failed} failed` : "none failed"}${warned ? `, ${warned} warning${warned === 1 ? "" : "s"}` : ""}`;
  const box = gridTable("checks-table", ["check", "verdict", "value", "limit", "message"], body, caption);
  box.querySelectorAll("tbody tr").forEach((tr, i) => {
    tr.dataset.verdict = verdict(sorted[i]);
    tr.dataset.check = sorted[i].name;
  });
  return box;
}
