// Past sessions: one row each, newest first, each reachable by keyboard (its id is a button), the shown
// session highlighted and kept in view in the list; choosing one brings the Session panel into view.

import { API } from "./api.js";
import { page } from "./state.js";
import { $, FINAL, el } from "./util.js";

let onSelect = () => {};
let signature = "";

export function setUpHistory(fn) {
  onSelect = fn;
}

/** Show session `id` in the Session and Results panels (the operator chose it). */
export function choose(id) {
  select(id);
}

function select(id) {
  page.current = id;
  page.chosen = true;
  markSelected(false);
  onSelect();
  const panel = $("session-section");
  const box = panel.getBoundingClientRect();
  if (box.top < 0 || box.bottom > window.innerHeight) panel.scrollIntoView({ block: "start", behavior: "instant" });
}

function row(s) {
  const open = el(
    "button",
    { type: "button", className: "row-open", "aria-label": `show session ${s.id} (${s.kind}, ${s.state})` },
    s.id,
  );
  open.addEventListener("click", () => select(s.id));
  const steps = s.progress.total ? `${s.progress.done} / ${s.progress.total}` : "—";
  const report = el("td");
  if (FINAL.has(s.state)) {
    report.append(el("a", { href: `${API}/sessions/${s.id}/report.html`, target: "_blank", rel: "noopener" }, "report"));
  }
  const tr = el(
    "tr",
    { dataset: { id: s.id } },
    el("td", {}, open),
    el("td", {}, s.kind),
    el("td", {}, el("span", { className: "state", dataset: { state: s.state } }, s.state.replace("_", " "))),
    el("td", { className: "n" }, steps),
    el("td", {}, s.created_at.replace("T", " ").slice(0, 19)),
    report,
  );
  tr.addEventListener("click", (ev) => {
    if (ev.target.closest("a, button")) return;
    select(s.id);
  });
  return tr;
}

/** Highlight the shown session's row; keep it in view inside the list (not the page) when asked. */
function markSelected(scroll) {
  for (const tr of $("sessions").tBodies[0].rows) {
    const on = tr.dataset.id === page.current;
    tr.classList.toggle("selected", on);
    tr.setAttribute("aria-current", on ? "true" : "false");
    if (on && scroll) {
      const box = $("sessions-scroll");
      const top = tr.offsetTop - box.offsetTop;
      if (top < box.scrollTop || top + tr.offsetHeight > box.scrollTop + box.clientHeight) {
        box.scrollTop = Math.max(0, top - box.clientHeight / 3);
      }
    }
  }
}

/** Show the sessions (re-rendered only when they changed; the focused row keeps its focus). */
export function renderHistory(items) {
  page.history = items;
  const sig = JSON.stringify(items.map((s) => [s.id, s.state, s.progress.done, s.progress.total]));
  if (sig !== signature) {
    signature = sig;
    const focused = document.activeElement?.closest?.("#sessions tr")?.dataset.id;
    $("sessions").tBodies[0].replaceChildren(...items.map(row));
    if (focused) $("sessions").querySelector(`tr[data-id="${focused}"] .row-open`)?.focus();
  }
  markSelected(!page.chosen);
}
