// The station's scale calibration: the groove width a validation that passed every gate wrote (the
// session that wrote it, when, its checks), its history (nothing is ever deleted), and Revert, which asks
// first and says what the station will measure with afterwards. Read when the page opens, when a session
// ends or writes one, after a revert, and every half minute meanwhile (another client may revert).

import { api } from "./api.js";
import { choose } from "./history.js";
import { canAct, page } from "./state.js";
import { $, el, num } from "./util.js";

const MAX_AGE_MS = 30000;
const ROUTE = "/station/scale-calibration";

let shown = null; // {status, items}: the latest reading
let readAt = 0;
let reading = null;

const width = (cal) => `${num(cal.groove_width_mm, 5)} mm`;
const when = (iso) => (iso ? iso.replace("T", " ").slice(0, 19) : "—");

function sessionButton(sid) {
  if (!sid) return "no session";
  const b = el("button", { type: "button", className: "row-open", "aria-label": `show session ${sid}` }, sid);
  b.addEventListener("click", () => choose(sid));
  return b;
}

/** What a revert would go back to: {version, calibration} (calibration null: none), or null when the
 * history knows of nothing earlier. */
function revertTarget(items) {
  const latest = items[0];
  if (!latest || latest.previous === null || latest.previous === undefined) return null;
  if (latest.previous === 0) return { version: 0, calibration: null };
  const entry = items.find((e) => e.version === latest.previous);
  return entry ? { version: entry.version, calibration: entry.calibration } : null;
}

function describeTarget(t) {
  if (!t.calibration) return "no scale calibration: the station measures with the artifact's nominal groove width again";
  return `version ${t.version}: groove width ${width(t.calibration)}, from session ${t.calibration.session_id || "—"}`;
}

function actionText(e) {
  if (e.action === "revert") return `revert to ${e.restores ? `version ${e.restores}` : "none"}`;
  if (e.action === "found") return "found in the data directory";
  return "validation";
}

function render() {
  if (!shown) return;
  const { status, items } = shown;
  const cal = status.calibration;
  const current = $("scale-current");
  current.dataset.version = cal ? String(cal.version ?? "") : "none";
  if (!cal) {
    current.replaceChildren(
      "None: the station measures with the artifact's nominal groove width. A validation that passes every check writes one.",
    );
  } else {
    const checks = Array.isArray(cal.checks) ? cal.checks : [];
    const passed = checks.filter((c) => c.passed).length;
    current.replaceChildren(
      el("strong", { id: "scale-width" }, `groove width ${width(cal)}`),
      ` (standard uncertainty ${num(cal.u_mm, 5)} mm), version ${num(cal.version)}, from validation session `,
      sessionButton(cal.session_id),
      `, written ${when(status.entry?.written_at)} UTC${checks.length ? `; it passed ${passed} of its ${checks.length} checks` : ""}.`,
    );
  }
  const rows = items.map((e) => {
    const tr = el(
      "tr",
      { dataset: { version: String(e.version) } },
      el("td", { className: "n" }, num(e.version)),
      el("td", {}, when(e.written_at)),
      el("td", {}, actionText(e)),
      el("td", { className: "n" }, e.calibration ? width(e.calibration) : "none (nominal)"),
      el("td", {}, e.calibration ? sessionButton(e.calibration.session_id) : "—"),
    );
    const isCurrent = cal ? e.version === cal.version : false;
    tr.classList.toggle("selected", isCurrent);
    if (isCurrent) tr.setAttribute("aria-current", "true");
    return tr;
  });
  const table = el(
    "table",
    { id: "scale-history" },
    el("caption", {}, `History (${items.length} change${items.length === 1 ? "" : "s"}, newest first; nothing is deleted)`),
    el(
      "thead",
      {},
      el("tr", {}, ...["version", "written (UTC)", "change", "groove width", "session"].map((h) => el("th", { scope: "col" }, h))),
    ),
    el("tbody", {}, ...rows),
  );
  $("scale-history-box").replaceChildren(...(items.length ? [table] : []));
  updateScaleControls();
}

/** Revert is offered when the history knows what came before; off while a session runs (409). */
export function updateScaleControls() {
  const target = shown ? revertTarget(shown.items) : null;
  const button = $("scale-revert");
  button.hidden = !target;
  button.disabled = !(target && canAct() && !page.running);
  button.textContent = target ? `Revert to ${target.calibration ? `version ${target.version}` : "none"}…` : "Revert…";
  button.title = page.running ? `possible once session ${page.running} has ended` : "";
  if (!target || page.running) $("scale-revert-confirm").hidden = true;
  $("scale-revert-yes").disabled = !(canAct() && !page.running);
}

/** Read the scale calibration and its history (at most every half minute unless `force`). */
export async function loadScale(force = false) {
  if (!force && Date.now() - readAt < MAX_AGE_MS) return;
  if (reading) return reading;
  reading = (async () => {
    try {
      const [status, history] = await Promise.all([api("GET", ROUTE), api("GET", `${ROUTE}/history`)]);
      shown = { status, items: history.items };
      readAt = Date.now();
      render();
    } catch (e) {
      $("scale-message").textContent = `the scale calibration cannot be read: ${e.message}`;
    } finally {
      reading = null;
    }
  })();
  return reading;
}

function offerRevert() {
  const target = shown ? revertTarget(shown.items) : null;
  if (!target) return;
  const cal = shown.status.calibration;
  const now = cal ? `version ${cal.version} (${width(cal)})` : "the current one";
  $("scale-revert-text").replaceChildren(
    el("strong", {}, "Revert the scale calibration?"),
    ` Back to ${describeTarget(target)}. Sessions started from now on measure with it; ${now} stays in the history.`,
  );
  $("scale-revert-confirm").hidden = false;
  $("scale-revert-no").focus();
}

async function revert() {
  $("scale-revert-confirm").hidden = true;
  $("scale-message").textContent = "reverting…";
  try {
    const reply = await api("POST", `${ROUTE}/revert`);
    const cal = reply.calibration;
    $("scale-message").textContent = cal
      ? `reverted: version ${num(cal.version)}, groove width ${width(cal)} (from session ${cal.session_id || "—"})`
      : "reverted: no scale calibration; the station measures with the nominal groove width";
  } catch (e) {
    $("scale-message").textContent = `not reverted: ${e.message}`;
  }
  await loadScale(true);
}

export function setUpScale() {
  $("scale-revert").addEventListener("click", offerRevert);
  $("scale-revert-yes").addEventListener("click", revert);
  $("scale-revert-no").addEventListener("click", () => {
    $("scale-revert-confirm").hidden = true;
    $("scale-revert").focus();
  });
}
