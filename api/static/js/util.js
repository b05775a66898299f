// Small helpers shared by the page's modules: element look-up and creation, number and time formats.

export const $ = (id) => document.getElementById(id);

export const FINAL = new Set(["stopped", "aborted", "failed", "succeeded", "interrupted"]);
/** Final states the API resumes (POST .../actions {"action": "resume"}). */
export const RESUMABLE = new Set(["interrupted", "stopped", "failed", "aborted"]);
export const MM_PER_IN = 25.4;

/** An element: el("td", {className: "n"}, "text", child, ...). */
export function el(tag, props = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(props)) {
    if (v === undefined || v === null) continue;
    if (k === "dataset") Object.assign(node.dataset, v);
    else if (k.startsWith("aria-") || k === "role" || k === "for" || k === "scope") node.setAttribute(k, v);
    else node[k] = v;
  }
  for (const c of children) if (c !== undefined && c !== null) node.append(c);
  return node;
}

/** A number as people read it: integers as integers, others to `digits` significant places after the point. */
export function num(v, digits = 4) {
  if (typeof v !== "number") return v === null || v === undefined ? "—" : String(v);
  if (!Number.isFinite(v)) return String(v);
  if (Number.isInteger(v)) return String(v);
  return v.toFixed(digits);
}

/** A length in um with its unit. */
export const um = (v, digits = 2) => (typeof v === "number" ? `${num(v, digits)} µm` : "—");

/** A micrometer reading: inches to the 0.0001 in the dial shows. */
export const inches = (v) => `${v.toFixed(4)} in`;

/** HH:MM:SS of a Date, local time, 24 h. */
export function clock(d) {
  const p = (n) => String(n).padStart(2, "0");
  return `${p(d.getHours())}:${p(d.getMinutes())}:${p(d.getSeconds())}`;
}

/** Seconds as "about 55 s", "about 3 min 20 s". */
export function duration(s) {
  const t = Math.max(0, Math.round(s));
  if (t < 90) return `${t} s`;
  const m = Math.floor(t / 60);
  return `${m} min ${String(t % 60).padStart(2, "0")} s`;
}

/** A key-value table: rows of [label, value]. */
export function kvTable(id, rows, caption) {
  const table = el("table", { id, className: "kv" });
  if (caption) table.append(el("caption", {}, caption));
  for (const [k, v] of rows) {
    const tr = table.insertRow();
    tr.append(el("th", { scope: "row" }, k), el("td", { className: "n" }, v));
  }
  return table;
}

/** A data table with a header row, wrapped in a horizontally scrolling box (readable at 800 px). */
export function gridTable(id, headers, rows, caption) {
  const table = el("table", { id });
  if (caption) table.append(el("caption", {}, caption));
  const head = el("tr", {}, ...headers.map((h) => el("th", { scope: "col" }, h)));
  table.append(el("thead", {}, head));
  const body = el("tbody");
  for (const r of rows) body.append(el("tr", {}, ...r.map((c) => el("td", {}, c))));
  table.append(body);
  return el("div", { className: "scroll" }, table);
}
