// Jog and teach (issue 23): the jog panel beside the live view (a step size, joint and camera-frame
// buttons), the teach buttons (reference, an artifact by name, the sensor mount) showing what was
// written, and the "Safety in force" panel (GET /station/safety). Every button that moves the arm is off,
// with the reason beside it, when the API would refuse it: a client on another machine, a latched stop,
// a session running, no token.

import { api } from "./api.js";
import { idleTick } from "./live.js";
import { canAct, mayMove, page } from "./state.js";
import { $, el, num } from "./util.js";

const STEPS = [0.01, 0.1, 1, 5];
const DEFAULT_STEP = 1;
const CAMERA_AXES = [
  ["x", "x (image right)", "mm"],
  ["y", "y (image down)", "mm"],
  ["z", "z (toward the work)", "mm"],
  ["turn", "turn (about the axis)", "°"],
];
const TEACH_TIMEOUT_MS = 900000;

let refresh = () => {};
let busy = false; // a jog or a teach of this page's is under way
let safety = null; // the latest GET /station/safety

const joints = (a) => (Array.isArray(a) ? a.map((v) => num(v, 3)).join(", ") : "—");

/** Why the arm may not be moved from this page now; null when it may. */
export function motionBlocked() {
  const r = page.station?.robot;
  if (!canAct()) return "log in with the URL station serve printed to move the arm";
  if (!r) return "this station has no robot";
  if (!mayMove())
    return "this page is on another machine: the arm moves only from the station itself (its page at 127.0.0.1), unless the service runs with station serve --allow-remote-motion";
  if (page.running) return `session ${page.running} is running and owns the arm: jog once it has ended (or stop it)`;
  if (typeof r.latched === "string" && r.latched !== "") return "a stop is latched: acknowledge it at the station (Robot panel) first";
  if (r.state !== "idle") return `the robot is ${String(r.state).replace("_", " ")}: wait until it is idle`;
  if (busy || page.moving) return "the arm is moving: wait for it to stop";
  return null;
}

function stepButtons(prefix, label, data) {
  return el(
    "div",
    { className: "jog-row" },
    el("span", { className: "jog-label" }, label),
    el("button", { type: "button", id: `${prefix}-minus`, className: "jog", dataset: { ...data, sign: "-1" }, "aria-label": `${label} minus` }, "−"),
    el("button", { type: "button", id: `${prefix}-plus`, className: "jog", dataset: { ...data, sign: "1" }, "aria-label": `${label} plus` }, "+"),
  );
}

function build() {
  $("jog-step").replaceChildren(
    ...STEPS.map((s) => el("option", { value: String(s), selected: s === DEFAULT_STEP }, `${s}`)),
  );
  $("jog-joints").replaceChildren(
    ...[1, 2, 3, 4, 5, 6].map((j) => stepButtons(`jog-j${j}`, `J${j} (°)`, { mode: "joint", joint: String(j) })),
  );
  $("jog-camera").replaceChildren(
    ...CAMERA_AXES.map(([axis, label, unit]) => stepButtons(`jog-${axis}`, `${label} (${unit})`, { mode: "camera", axis })),
  );
}

/** Enable what the API would accept now; say why the rest is off. */
export function updateJogControls() {
  const why = motionBlocked();
  for (const b of document.querySelectorAll("#jog-section button.jog, #teach-section button.teach")) b.disabled = why !== null;
  $("teach-artifact").disabled = why !== null || !/^[A-Za-z0-9][A-Za-z0-9_.-]{0,39}$/.test($("teach-artifact-name").value);
  for (const id of ["jog-reason", "teach-reason"]) {
    $(id).textContent = why ? `Off: ${why}.` : "";
    $(id).hidden = why === null;
  }
  $("jog-section").dataset.allowed = String(why === null);
}

async function moveArm(what, run) {
  busy = true;
  page.moving = true;
  updateJogControls();
  try {
    return await run();
  } catch (e) {
    what(e);
    return null;
  } finally {
    busy = false;
    page.moving = false;
    refresh();
    idleTick(true); // the camera's view from where the arm stopped
  }
}

async function jog(button) {
  const step = Number($("jog-step").value);
  const delta = Number(button.dataset.sign) * step;
  const body =
    button.dataset.mode === "joint"
      ? { mode: "joint", joint: Number(button.dataset.joint), delta_deg: delta }
      : { mode: "camera", axis: button.dataset.axis, delta };
  const out = $("jog-result");
  out.dataset.state = "moving";
  out.textContent = "jogging…";
  const reply = await moveArm(
    (e) => {
      out.dataset.state = "refused";
      out.textContent = `not jogged (nothing moved): ${e.message}`;
    },
    () => api("POST", "/station/robot/jog", body, { timeoutMs: 120000 }),
  );
  if (!reply) return;
  out.dataset.state = "done";
  const what = reply.kind === "joint" ? `J${reply.axis}` : `camera ${reply.axis}`;
  const world = Array.isArray(reply.world_mm_deg) ? `; WORLD ${joints(reply.world_mm_deg)}` : "";
  out.textContent = `${what} ${reply.delta > 0 ? "+" : ""}${num(reply.delta, 3)} ${reply.unit} at ${num(reply.speed_pct, 1)} %: joints ${joints(reply.joints_deg)}°${world}`;
}

async function teach(path, label) {
  const out = $("teach-result");
  out.dataset.state = "moving";
  out.replaceChildren(`teaching ${label}: the arm moves in small checked steps…`);
  const reply = await moveArm(
    (e) => {
      out.dataset.state = "refused";
      out.replaceChildren(el("span", { className: "error" }, `${label} not taught (nothing written): ${e.message}`));
    },
    () => api("POST", path, undefined, { timeoutMs: TEACH_TIMEOUT_MS }),
  );
  if (!reply) return;
  out.dataset.state = "done";
  out.replaceChildren(
    el("p", {}, `${label} written into ${reply.config} (the old file is ${reply.backup}):`),
    el("ul", { id: "teach-changes", className: "mono" }, ...reply.changes.map((c) => el("li", {}, c))),
  );
}

/** The "Safety in force" panel. */
export async function loadSafety() {
  try {
    safety = await api("GET", "/station/safety");
  } catch {
    return; // the page says why elsewhere (connection, login); the panel keeps its last reading
  }
  const s = safety;
  const latch = s.latched
    ? `latched (${s.latched}): ${s.acknowledge_how}`
    : "not latched; after any stop, E-stop or controller error it holds until acknowledged at the station";
  const rows = [
    ["keep-out", "Keep-out volumes", s.robot ? `${s.keep_out_volumes} configured volume${s.keep_out_volumes === 1 ? "" : "s"} checked along every path (jog and home included), with the table plane${s.min_camera_height_mm !== null ? ` and the camera ${num(s.min_camera_height_mm, 1)} mm above it` : ""}` : "no robot"],
    ["speed-cap", "Speed cap", `${num(s.max_speed_pct, 1)} % (no plan, jog or Align exceeds it; set by ${s.speed_cap_setting}); jogs run at ${num(s.jog_speed_pct, 1)} %`],
    ["latch", "Stop latch", latch],
    ["remote", "Remote motion", s.remote_motion ? "allowed: any client with the token may move the arm (station serve --allow-remote-motion)" : "refused: only the station itself may move the arm"],
    ["local-ack", "Local acknowledgement", `${s.local_acknowledgement ? "required" : "not required"}: a latched stop is released only by a person at the station${s.local ? " (this page is on the station)" : " (this page is not on the station: it cannot release one)"}`],
  ];
  $("safety").replaceChildren(
    ...rows.flatMap(([rule, name, text]) => [
      el("dt", { dataset: { rule } }, name),
      el("dd", { id: `safety-${rule}`, dataset: { rule } }, text),
    ]),
  );
  $("safety-section").dataset.latched = String(Boolean(s.latched));
}

export function setUpJog(refreshFn) {
  refresh = refreshFn;
  build();
  $("jog-section").addEventListener("click", (ev) => {
    const b = ev.target.closest("button.jog");
    if (b && !b.disabled && motionBlocked() === null) jog(b);
  });
  $("teach-reference").addEventListener("click", () => teach("/station/teach/reference", "the reference pose"));
  $("teach-sensor-mount").addEventListener("click", () => teach("/station/teach/sensor-mount", "the sensor mount"));
  $("teach-artifact").addEventListener("click", () => {
    const name = $("teach-artifact-name").value;
    teach(`/station/teach/artifact/${encodeURIComponent(name)}`, `artifact ${name}`);
  });
  $("teach-artifact-name").addEventListener("input", updateJogControls);
  updateJogControls();
}
