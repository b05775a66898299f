// The operator page: a client of the station's API only. HTTP is the source of truth; the event stream
// says when to read again (and brings the live measurements), a poll every two seconds covers a lost
// stream and tells a dead service from a quiet one.

import { Unreachable, api, watch } from "./api.js";
import { onConnection, suspect } from "./connection.js";
import { loadSafety, setUpJog, updateJogControls } from "./jog.js";
import { onEvent, openEvents } from "./events.js";
import { setKinds, setUpForm } from "./form.js";
import { renderHistory, setUpHistory } from "./history.js";
import { idleTick, sessionCaptured, sessionChanged } from "./live.js";
import { onAnswered, setUpPrompt, showPrompt } from "./prompt.js";
import { setUpResults, showResults } from "./results.js";
import { renderState, say, setUpSession, showSession, tick, updateControls } from "./session.js";
import { canRead, page } from "./state.js";
import { loadScale, setUpScale, updateScaleControls } from "./scale.js";
import { setUpStation, showDevices, showRobot, updateRobotControls } from "./station.js";
import { $, FINAL } from "./util.js";

const POLL_MS = 2000;
const ACCESS_POLL_MS = 5000;
const EVENT_DELAY_MS = 100;

let refreshing = false;
let again = false;
let scheduled = null;
let accessTimer = null;

/** What this client may do (GET /access needs no token): say so before anything fails. */
async function checkAccess() {
  try {
    page.access = await api("GET", "/access");
  } catch {
    return;
  }
  const a = page.access;
  document.body.dataset.access = a.authenticated ? "control" : a.open_reads ? "read" : "none";
  const note = $("auth-note");
  note.hidden = a.authenticated;
  if (!a.authenticated) {
    note.textContent = a.open_reads
      ? "Read-only: open the login URL that station serve printed (it ends in ?token=...) to control the station."
      : "Not logged in: open the login URL that station serve printed (it ends in ?token=...): without it this page can show nothing of the station.";
  }
  if (a.authenticated) openEvents();
  if (!a.authenticated && accessTimer === null) accessTimer = setInterval(recheckAccess, ACCESS_POLL_MS);
  if (a.authenticated && accessTimer !== null) {
    clearInterval(accessTimer);
    accessTimer = null;
  }
  updateControls();
}

async function recheckAccess() {
  const before = JSON.stringify(page.access);
  await checkAccess();
  if (JSON.stringify(page.access) !== before) refresh();
}

async function loadPlans() {
  if (page.plans.size) return;
  const doc = await api("GET", "/plans");
  for (const p of doc.plans) page.plans.set(p.name, p);
}

/** Read everything the page shows; calls while one runs are coalesced into one more. */
async function refresh() {
  if (page.connection !== "ok" || !canRead()) return;
  if (refreshing) {
    again = true;
    return;
  }
  refreshing = true;
  const epoch = page.epoch;
  const fresh = () => page.epoch === epoch && page.actions === 0;
  try {
    const station = await api("GET", "/station");
    page.station = station;
    showDevices(station);
    const running = station.session ? station.session.id : null;
    if (running !== page.running) {
      page.running = running;
      sessionChanged();
      loadScale(true); // a validation that passed its checks writes the scale calibration as it ends
    }
    showRobot(station);
    loadSafety();
    loadScale();
    await loadPlans();
    setKinds(station.plans.filter((n) => page.plans.has(n)));
    const list = await api("GET", "/sessions?limit=20");
    if (running && !page.chosen) page.current = running;
    else if (!page.current && list.items.length) page.current = list.items[0].id;
    renderHistory(list.items);
    let s = null;
    if (page.current) s = list.items.find((x) => x.id === page.current) || (await api("GET", `/sessions/${page.current}`));
    // the station was read first: a session that ended between the two reads is not running any more
    if (s && FINAL.has(s.state) && page.running === s.id) {
      page.running = null;
      sessionChanged();
      loadScale(true);
    }
    showSession(s);
    showPrompt(await api("GET", "/prompt"));
    await showResults(s, fresh);
    if (fresh()) idleTick(); // else the action that made this reading stale reads again once it has answered
  } catch (e) {
    if (!(e instanceof Unreachable)) say(e.message);
  } finally {
    refreshing = false;
    updateControls();
    updateJogControls();
    if (again) {
      again = false;
      refresh();
    }
  }
}

/** Events come in bursts (a replay after reconnecting): one read after the burst. */
function soon() {
  if (scheduled !== null) return;
  scheduled = setTimeout(() => {
    scheduled = null;
    refresh();
  }, EVENT_DELAY_MS);
}

onEvent((type, e) => {
  if (type === "measurement") {
    sessionCaptured(e.session_id, { ...e.data, z_mm: e.data.z_mm });
    return;
  }
  if (type === "image_captured") return; // its measurement follows
  if (type === "scale_calibration") loadScale(true);
  soon();
});

onConnection("lost", () => {
  renderState();
  updateControls();
});
onConnection("restored", async () => {
  await checkAccess();
  loadScale(true);
  await refresh();
  idleTick(true);
});

watch({ unreachable: suspect, unauthorized: () => recheckAccess() });

document.addEventListener("DOMContentLoaded", async () => {
  setUpForm();
  $("kind").addEventListener("change", () => updateControls()); // Start may depend on the kind (motion)
  setUpPrompt();
  setUpResults();
  setUpHistory(refresh);
  setUpStation(refresh);
  setUpJog(refresh);
  setUpScale();
  setUpSession(refresh, () => {
    updateRobotControls();
    updateJogControls();
    updateScaleControls();
  });
  onAnswered(refresh);
  await checkAccess();
  await refresh();
  idleTick(true);
  setInterval(refresh, POLL_MS);
  setInterval(() => {
    tick();
    idleTick();
  }, 1000);
  document.addEventListener("visibilitychange", () => idleTick(true));
});
