// The live view: the camera now (between sessions), or the running session's latest capture, each with its
// measurement drawn and its numbers (centre in px and mm, the error code when it fails) underneath.
//
// Quiet: no request that is known to fail. The session's latest capture is asked for only after the
// session has reported a measured capture (the stream's `measurement` event); the camera only while no
// session owns it; one picture in flight at a time.

import { image } from "./api.js";
import { canRead, page } from "./state.js";
import { $, el, num } from "./util.js";

const IDLE_MS = 3000;

let inflight = false;
let queued = null; // the next picture to load once the one in flight is in
let shownUrl = null;
let lastIdle = 0;
let shownSession = null; // the session whose capture is shown

/** The numbers of a measurement ({ok, center_px, center_mm, code, error}) under the picture. */
export function showNumbers(m, where) {
  const dl = $("live-numbers");
  if (!m) {
    dl.replaceChildren();
    return;
  }
  const rows = [];
  if (m.ok) {
    const px = m.center_px || [];
    const mm = m.center_mm || [];
    rows.push(["centre (px)", `x ${num(px[0], 3)}, y ${num(px[1], 3)}`]);
    rows.push(["centre (mm)", `x ${num(mm[0], 4)}, y ${num(mm[1], 4)}`]);
  } else {
    rows.push(["measurement", `failed: ${m.code || "error"}`]);
    if (m.error) rows.push(["why", m.error]);
  }
  if (typeof m.z_mm === "number") rows.push(["distance (mm)", num(m.z_mm, 3)]);
  if (where) rows.push(["of", where]);
  dl.dataset.ok = m.ok ? "true" : "false";
  dl.replaceChildren(...rows.flatMap(([k, v]) => [el("dt", {}, k), el("dd", {}, v)]));
}

/** The picture's measurement from its response headers: the numbers (X-Measurement, JSON), else the
 * verdict alone (X-Measurement-Ok, -Code, -Error); null without either. */
function measurementOf(headers) {
  const doc = headers.get("X-Measurement");
  if (doc) return JSON.parse(doc);
  const ok = headers.get("X-Measurement-Ok");
  if (ok === null) return null;
  return { ok: ok === "true", code: headers.get("X-Measurement-Code"), error: headers.get("X-Measurement-Error") };
}

async function load(job) {
  if (inflight) {
    queued = job;
    return;
  }
  inflight = true;
  try {
    const { url, headers } = await image(job.path);
    const img = $("live");
    img.src = url;
    img.classList.remove("stale");
    if (shownUrl) URL.revokeObjectURL(shownUrl);
    shownUrl = url;
    $("live-caption").textContent = job.caption;
    let numbers = job.measurement;
    if (!numbers) numbers = measurementOf(headers);
    showNumbers(numbers, job.where);
  } catch (e) {
    // a session took the camera meanwhile, or the service went away: say so, keep the last picture
    $("live-caption").textContent = `no new picture: ${e.message}`;
  } finally {
    inflight = false;
    const next = queued;
    queued = null;
    if (next) load(next);
  }
}

/** A capture of the running session was measured (its `measurement` event): show it with its numbers. */
export function sessionCaptured(sessionId, data) {
  if (sessionId !== page.running) return;
  shownSession = sessionId;
  load({
    path: `/sessions/${sessionId}/latest.png`,
    caption: `session ${sessionId}: its latest capture and the measurement drawn on it`,
    measurement: data ? { ...data } : null,
    where: `capture ${data?.capture_id ?? "?"}`,
  });
}

/** The station changed (a session started or ended): say what the view shows now. */
export function sessionChanged() {
  if (page.running && shownSession !== page.running) {
    $("live-caption").textContent = `session ${page.running} is running: its first capture shows here once it is measured`;
    $("live").classList.add("stale"); // the camera's last picture, from before the session
    showNumbers(null);
  }
}

/** Between sessions, every few seconds: the camera now. */
export function idleTick(force = false) {
  const s = page.station;
  if (!canRead() || page.connection !== "ok" || page.running || page.starting || page.actions || page.moving || !s) return;
  if (!s.devices || !s.devices.camera || (s.worker && s.worker.alive === false)) return;
  if (s.devices.robot && s.devices.robot.state === "busy") return; // the arm is on its way somewhere
  if (document.visibilityState !== "visible") return;
  const now = Date.now();
  if (!force && now - lastIdle < IDLE_MS) return;
  lastIdle = now;
  shownSession = null;
  load({ path: "/camera/snapshot.png?overlay=true", caption: "the camera now, with the measurement drawn on it" });
}
