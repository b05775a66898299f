// The operator prompt (the manual table's micrometers): a panel beside the live view, never a modal, so
// Pause, Stop and Abort stay usable while it is open. It says which position of how many it is and
// whether the move is the overshoot before a backwards approach; every length is in the micrometers'
// inches with the table position in mm in brackets. Cancel asks first and says what it does.

import { api } from "./api.js";
import { canAct } from "./state.js";
import { $, MM_PER_IN, el, num } from "./util.js";

let shown = null; // the prompt in the panel
let afterAnswer = () => {};

/** Who re-reads the station once the operator has answered. */
export function onAnswered(fn) {
  afterAnswer = fn;
}

export const shownPrompt = () => shown;

function moveText(d) {
  if (d.content !== undefined) {
    const was = d.was === "unknown" ? "The station does not know what lies there now." : `The station last knew the ${d.was} there.`;
    return `${was} The session goes on once you confirm; nothing moves before.`;
  }
  if (d.purpose === "resume_check") {
    const then = d.move === "overshoot" ? " First the overshoot before it, to take up the backlash." : "";
    return `The last confirmed position again, after the interruption: the session continues only if the camera measures it where it did before.${then}`;
  }
  if (d.move === "overshoot") {
    return "Overshoot before a backwards move: set the micrometers past the position first (this takes up the backlash); the next prompt is the position itself.";
  }
  if (d.move === "position") return "The position itself: the camera captures after you confirm.";
  return "";
}

function title(p) {
  const d = p.details || {};
  if (p.kind === "table_content") return "Operator: what lies on the X-Y table";
  if (d.position !== undefined && d.positions !== undefined) {
    const which = `position ${num(Number(d.position))} of ${num(Number(d.positions))}`;
    if (d.purpose === "resume_check") return `Operator: ${which} again (the resume's check)`;
    const what = d.move === "overshoot" ? "overshoot before" : "set";
    return `Operator: ${what} ${which}`;
  }
  return "Operator";
}

/** The table position (mm) a reading puts an axis at: the prompt's own mm target, moved by the change. */
function mmOf(field, value, details) {
  const target = details[`${field.name[0]}_mm`];
  if (typeof target !== "number" || field.requested == null || !Number.isFinite(value)) return null;
  return target + (value - field.requested) * MM_PER_IN;
}

function fieldRow(field, details) {
  const id = `prompt-field-${field.name}`;
  const input = el("input", {
    id,
    type: "number",
    step: field.unit === "in" ? "0.0001" : "any",
    name: field.name,
    inputMode: "decimal",
    value: field.requested != null ? (field.unit === "in" ? field.requested.toFixed(4) : String(field.requested)) : "",
  });
  const mm = el("span", { className: "mm", id: `${id}-mm` });
  const update = () => {
    const v = mmOf(field, Number(input.value), details);
    mm.textContent = v === null ? "" : `(${v.toFixed(4)} mm)`;
  };
  input.addEventListener("input", update);
  update();
  return el("div", { className: "field" }, el("label", { for: id }, `${field.label} (${field.unit})`), input, mm);
}

/** Show the open prompt (or hide the panel when none is open). */
export function showPrompt(p) {
  const panel = $("prompt-panel");
  if (!p) {
    panel.hidden = true;
    shown = null;
    $("prompt-cancel-confirm").hidden = true;
    return;
  }
  if (shown && shown.id === p.id && !panel.hidden) {
    updatePromptControls();
    return;
  }
  const first = shown === null;
  shown = p;
  const d = p.details || {};
  panel.dataset.promptId = p.id;
  panel.dataset.move = d.move || "";
  $("prompt-title").textContent = title(p);
  $("prompt-move").textContent = moveText(d);
  let message = p.message;
  if (typeof d.x_mm === "number" && typeof d.y_mm === "number") {
    message += ` (table at X ${d.x_mm.toFixed(4)} mm, Y ${d.y_mm.toFixed(4)} mm)`;
  }
  $("prompt-message").textContent = message;
  $("prompt-error").textContent = "";
  $("prompt-fields").replaceChildren(...p.fields.map((f) => fieldRow(f, d)));
  $("prompt-cancel-confirm").hidden = true;
  panel.hidden = false;
  updatePromptControls();
  if (first && canAct()) panel.scrollIntoView({ block: "nearest" });
}

export function updatePromptControls() {
  const ok = canAct() && shown !== null;
  for (const id of ["prompt-confirm", "prompt-cancel", "prompt-cancel-yes", "prompt-cancel-no"]) $(id).disabled = !ok;
  for (const input of $("prompt-fields").querySelectorAll("input")) input.disabled = !ok;
}

async function confirm(ev) {
  ev.preventDefault();
  if (!shown) return;
  const readings = {};
  for (const input of $("prompt-fields").querySelectorAll("input")) {
    if (input.value === "") continue;
    const v = Number(input.value);
    if (!Number.isFinite(v)) {
      $("prompt-error").textContent = `${input.name}: "${input.value}" is not a number; type the reading in inches, e.g. 0.5100`;
      return;
    }
    readings[input.name] = v;
  }
  const id = shown.id;
  $("prompt-confirm").disabled = true;
  try {
    await api("POST", `/prompt/${id}/confirm`, { readings });
    shown = null;
    $("prompt-panel").hidden = true;
  } catch (e) {
    $("prompt-error").textContent = e.message;
    updatePromptControls();
  }
  afterAnswer();
}

function askCancel() {
  $("prompt-cancel-confirm").hidden = false;
  $("prompt-cancel-no").focus();
}

async function cancel() {
  if (!shown) return;
  const id = shown.id;
  const position = shown.details?.position;
  try {
    await api("POST", `/prompt/${id}/cancel`, {
      reason: `cancelled in the operator page${position !== undefined ? ` at position ${num(Number(position))}` : ""}`,
    });
    shown = null;
    $("prompt-panel").hidden = true;
  } catch (e) {
    $("prompt-error").textContent = e.message;
  }
  $("prompt-cancel-confirm").hidden = true;
  afterAnswer();
}

export function setUpPrompt() {
  $("prompt-form").addEventListener("submit", confirm);
  $("prompt-cancel").addEventListener("click", askCancel);
  $("prompt-cancel-yes").addEventListener("click", cancel);
  $("prompt-cancel-no").addEventListener("click", () => {
    $("prompt-cancel-confirm").hidden = true;
    $("prompt-cancel").focus();
  });
}
