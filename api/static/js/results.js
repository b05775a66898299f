// The Results panel of an ended session: how it ended (never an empty panel: a failed session says why,
// shows what it measured and how to continue), its gates, its tables (kinds.js), its figures (open full
// size on click) and the downloads that exist for it.

import { API, api } from "./api.js";
import { checksTable, failedChecks, hasTable, resultTables, resumeRule } from "./kinds.js";
import { $, FINAL, RESUMABLE, el } from "./util.js";

let shownKey = null;

function status(s) {
  const r = s.results || {};
  const partial = Object.values(r.tests || {}).some((t) => t && t.partial) || r.partial === true;
  const has = Object.keys(r).length > 0;
  // the gates decided the state only when every step of the plan ran (else they judge partial results)
  const ran = s.progress && s.progress.total > 0 && s.progress.done >= s.progress.total;
  const failed = ran ? failedChecks(r.checks || r[r.kind]?.checks) : [];
  const box = el("div", { className: `status status-${s.state}`, id: "results-state" });
  if (s.state === "succeeded") {
    box.append(el("p", {}, `Session ${s.id} succeeded.`));
    if (partial) box.append(el("p", {}, "Some tests are partial: their N is below the cycles planned, and their RP is not in the headline."));
    return box;
  }
  box.append(el("p", {}, el("strong", {}, `Session ${s.id} ${s.state}`), s.error ? `: ${s.error}` : "."));
  if (failed.length) {
    // the gates refused what it measured: nothing is hidden, and nothing of it is used
    const names = failed.map((c) => c.name).join(", ");
    box.dataset.gates = "failed";
    box.append(el("p", {}, `Its results failed ${failed.length === 1 ? "a check" : `${failed.length} checks`} (${names}, marked below): they cannot be right, so they are kept and shown but not used${s.kind === "validation" ? " (the station's scale calibration was not written)" : ""}. Fix what the message says, then start a new session.`));
    return box;
  }
  box.append(el("p", {}, has ? "Its results below are partial: what it measured before it ended." : "It has no results: it ended before enough was measured."));
  if (RESUMABLE.has(s.state)) {
    box.append(el("p", {}, `Resume (above) continues it: ${resumeRule(s.kind)} The report keeps what it captured.`));
  }
  return box;
}

function figureButton(sid, name) {
  const src = `${API}/sessions/${sid}/figures/${encodeURIComponent(name)}`;
  const img = el("img", { src, alt: `figure ${name}` });
  const button = el("button", { type: "button", className: "figure", title: "open full size" }, img, el("span", {}, name));
  // a wide figure (a grid of panels) takes two columns where there are two
  img.addEventListener("load", () => button.classList.toggle("wide", img.naturalWidth > 1.6 * img.naturalHeight));
  button.addEventListener("click", () => openFigure(src, name));
  return button;
}

function openFigure(src, name) {
  const dialog = $("figure-dialog");
  $("figure-full").src = src;
  $("figure-full").alt = `figure ${name}, full size`;
  dialog.showModal();
}

function links(s) {
  const out = [[`${API}/sessions/${s.id}/report.html`, "HTML report"]];
  if (hasTable(s.kind, s.results)) out.push([`${API}/sessions/${s.id}/results?format=csv`, "table (CSV)"]);
  out.push([`${API}/sessions/${s.id}/results`, "results (JSON)"]);
  out.push([`${API}/sessions/${s.id}/export.zip`, "export (zip)"]);
  return out.map(([href, text]) => el("a", { href, target: "_blank", rel: "noopener" }, text));
}

/** Show the session's results when it has ended (hide the panel while it runs). `fresh()` says whether
 * the reading `s` comes from is still current (no action answered since): only then are its figures
 * asked for (a session resumed meanwhile has no report until it ends again). */
export async function showResults(s, fresh = () => true) {
  const section = $("results-section");
  if (!s || !FINAL.has(s.state)) {
    section.hidden = true;
    shownKey = null;
    return;
  }
  const key = `${s.id}:${s.updated_at}`;
  if (shownKey === key) return;
  shownKey = key;
  section.hidden = false;
  $("results-title").textContent = `Results of ${s.kind} session ${s.id}`;
  const r = s.results || {};
  const parts = [status(s)];
  const checks = checksTable(r.checks || r[r.kind]?.checks);
  if (checks) parts.push(checks);
  $("results-status").replaceChildren(...parts);
  $("results").replaceChildren(...(Object.keys(r).length ? resultTables(s.kind, r, s.params) : []));
  $("report-links").replaceChildren(...links(s).flatMap((a) => [a, " "]));
  $("figures").replaceChildren();
  delete $("figures").dataset.loaded;
  if (!fresh()) {
    shownKey = null; // shown again from the next reading
    return;
  }
  try {
    const figs = await api("GET", `/sessions/${s.id}/figures`);
    if (shownKey !== key) return;
    const pngs = figs.figures.filter((n) => n.endsWith(".png"));
    $("figures").replaceChildren(...pngs.map((n) => figureButton(s.id, n)));
  } catch (e) {
    $("figures").replaceChildren(el("p", { className: "error" }, `figures: ${e.message}`));
  }
  $("figures").dataset.loaded = key;
}

export function setUpResults() {
  $("figure-dialog").addEventListener("click", (ev) => {
    if (ev.target === $("figure-dialog")) $("figure-dialog").close(); // a click outside the figure
  });
}
