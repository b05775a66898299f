// The Session panel: the shown session's state, its progress with an ETA that counts down while it runs
// (and says "paused" when paused), and Pause / Resume / Stop / Abort, each enabled exactly when the API
// accepts it (Resume too for every ended state the API resumes). Starting a session lives here too.

import { api } from "./api.js";
import { formInputs, formParams, showRefusal } from "./form.js";
import { resumeRule } from "./kinds.js";
import { updatePromptControls } from "./prompt.js";
import { canAct, drives, mayMove, page } from "./state.js";
import { $, FINAL, RESUMABLE, duration } from "./util.js";

const ACTIVE = new Set(["idle", "running", "pausing", "paused", "awaiting_operator", "stopping", "aborting"]);
let eta = null; // {sid, value, at}: the service's estimate and when it was read, counted down here
let refresh = () => {};
let onControls = () => {};

export function say(text) {
  $("message").textContent = text || "";
}

function etaText(s) {
  const p = s.progress;
  if (FINAL.has(s.state) || p.total === 0) return "";
  if (s.state === "paused") return ": paused";
  if (s.state === "pausing") return ": pausing after this step";
  if (s.state === "stopping") return ": stopping after this step";
  if (s.state === "aborting") return ": aborting";
  if (!eta || eta.value === null || eta.value === undefined) return "";
  if (s.state === "awaiting_operator") return `: waiting for the operator; about ${duration(eta.value)} of work left`;
  const left = eta.value - (Date.now() - eta.at) / 1000;
  return left > 0 ? `, about ${duration(left)} left` : ", finishing";
}

function progressText(s) {
  const p = s.progress;
  if (p.total === 0) return FINAL.has(s.state) ? "no step of the plan was run" : "preparing";
  return `${p.done} / ${p.total} steps${etaText(s)}`;
}

/** Show a session in the panel (null: none yet). */
export function showSession(s) {
  page.session = s;
  $("current").hidden = !s;
  $("no-session").hidden = Boolean(s);
  if (!s) {
    updateControls();
    return;
  }
  $("session-id").textContent = s.id;
  $("session-kind").textContent = s.kind;
  const p = s.progress;
  // the service's estimate, counted down from when it was read; read again when it or the state changes
  // (after a pause the count starts again from the service's estimate, not from before the pause)
  if (!eta || eta.sid !== s.id || eta.value !== p.eta_s || eta.state !== s.state) {
    eta = { sid: s.id, value: p.eta_s, at: Date.now(), state: s.state };
  }
  renderState();
  updateControls();
}

/** State and progress as they are now (the connection may have been lost since the last reading). */
export function renderState() {
  const s = page.session;
  if (!s) return;
  const lost = page.connection !== "ok";
  const state = lost ? "unknown" : s.state;
  $("state").textContent = lost ? "unknown (service unreachable)" : s.state.replace("_", " ");
  $("state").dataset.state = state;
  const p = s.progress;
  $("progress").max = Math.max(p.total, 1);
  $("progress").value = Math.min(p.done, Math.max(p.total, 1));
  $("progress-text").textContent = lost ? `${p.done} / ${p.total} steps when last read; now unknown` : progressText(s);
  $("session-error").textContent = s.error || "";
}

/** Every second: the ETA counts down. */
export function tick() {
  const s = page.session;
  if (s && page.connection === "ok" && !FINAL.has(s.state)) $("progress-text").textContent = progressText(s);
}

/** Enable what the API would accept now; say why the rest is off. */
export function updateControls() {
  const s = page.session;
  const act = canAct();
  const state = s ? s.state : null;
  const other = page.running && s && page.running !== s.id;
  $("pause").disabled = !(act && (state === "running" || state === "awaiting_operator"));
  const moving = (kind) => mayMove() || !drives(kind);
  $("resume").disabled = !(
    act &&
    s !== null &&
    moving(s.kind) &&
    (state === "paused" || state === "pausing" || (RESUMABLE.has(state) && !page.running && !page.starting))
  );
  $("stop").disabled = !(act && ["running", "pausing", "paused", "awaiting_operator"].includes(state));
  $("abort").disabled = !(act && ACTIVE.has(state) && state !== "aborting" && state !== "idle");
  $("start").disabled = !(act && !page.running && !page.starting && moving($("kind").value));
  for (const input of formInputs()) input.disabled = !act;
  let note = "";
  if (page.connection !== "ok") note = "The service is unreachable: every control is off until it answers again.";
  else if (!page.access?.authenticated) note = "Read-only: log in with the URL that station serve prints to control the station.";
  else if (!mayMove() && ((s && drives(s.kind) && RESUMABLE.has(state)) || drives($("kind").value))) {
    note = "This page is not on the station: it can pause, stop and abort, and start re-analyses and sweeps; sessions that move the arm start and resume only from the station itself (station serve --allow-remote-motion lets other machines).";
  }
  else if (RESUMABLE.has(state) && page.running) note = `Resume is possible once session ${page.running} has ended.`;
  else if (RESUMABLE.has(state)) note = `Resume continues this session: ${resumeRule(s.kind)}`;
  else if (state === "awaiting_operator") {
    note = "Pause and Stop take effect at the end of this step, once its prompts are answered; Abort stops now.";
  }
  else if (other) note = `Session ${page.running} is running.`;
  $("control-note").textContent = note;
  $("start").title = page.running ? `session ${page.running} is running` : "";
  updatePromptControls();
  onControls();
}

async function act(action) {
  const s = page.session;
  if (!s) return;
  if (action === "abort") {
    $("abort-confirm").hidden = false;
    $("abort-yes").focus();
    return;
  }
  await send(s.id, action);
}

/** Run an action that may change what the station does; readings taken meanwhile are stale. */
export async function acting(fn) {
  page.actions += 1;
  page.epoch += 1;
  try {
    return await fn();
  } finally {
    page.actions -= 1;
    page.epoch += 1;
  }
}

async function send(id, action) {
  $(action).disabled = true;
  await acting(async () => {
    try {
      const s = await api("POST", `/sessions/${id}/actions`, { action });
      if (action === "resume" && !FINAL.has(s.state)) page.running = s.id; // a resumed ended session runs
      say("");
    } catch (e) {
      say(e.message);
    }
  });
  refresh();
}

async function start(ev) {
  ev.preventDefault();
  const params = formParams();
  if (params === null) return;
  page.starting = true;
  updateControls();
  $("start-error").textContent = "";
  await acting(async () => {
    try {
      const s = await api("POST", "/sessions", { kind: $("kind").value, params });
      page.current = s.id;
      page.running = s.id;
      page.chosen = false;
      say("");
    } catch (e) {
      showRefusal(e);
    } finally {
      page.starting = false;
    }
  });
  refresh();
}

export function setUpSession(refreshFn, onControlsFn) {
  refresh = refreshFn;
  onControls = onControlsFn;
  $("start-form").addEventListener("submit", start);
  for (const action of ["pause", "resume", "stop", "abort"]) $(action).addEventListener("click", () => act(action));
  $("abort-yes").addEventListener("click", async () => {
    $("abort-confirm").hidden = true;
    if (page.session) await send(page.session.id, "abort");
  });
  $("abort-no").addEventListener("click", () => {
    $("abort-confirm").hidden = true;
    $("abort").focus();
  });
}
