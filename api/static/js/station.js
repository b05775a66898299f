// The station: its devices in the header, and the robot's state and pose from the start (the service
// reads it between sessions), with "Move to the reference pose" whenever the arm is not at it.

import { api } from "./api.js";
import { canAct, page } from "./state.js";
import { $, clock, el, num } from "./util.js";

let refresh = () => {};

const onOff = (v, yes, no) => (v === true ? yes : v === false ? no : `${yes}: unknown`);
const joints = (a) => (Array.isArray(a) ? a.map((v) => num(v, 3)).join(", ") : "—");

export function showDevices(s) {
  $("station-name").textContent = s.name;
  $("devices").replaceChildren(
    ...Object.entries(s.devices).map(([name, d]) => {
      const model = d.identity?.model || d.identity?.port || "model not reported";
      return el("li", { dataset: { device: name, state: d.state } }, `${name}: ${model} (${d.state.replace("_", " ")})`);
    }),
  );
}

function stateText(r, s) {
  const model = s.devices?.robot?.identity?.model || "robot";
  if (r.state === "reading") return `${model}: reading its state…`;
  if (r.state === "unreachable") return `${model}: unreachable (${r.error}); check its cable and power`;
  if (r.state === "busy") return `${model}: another process's session holds the station (${r.error}); pose as last read`;
  if (r.state === "in_session") return `${model}: in a session, moving as its plan says; its pose is read again when it ends`;
  const facts = [onOff(r.power, "power on", "power off"), onOff(r.homed, "homed", "not homed")];
  if (r.at_reference === true) facts.push("at the reference pose");
  else if (r.at_reference === false) facts.push("not at the reference pose");
  return `${model}: idle, ${facts.join(", ")}`;
}

export function showRobot(s) {
  const r = s.robot;
  const section = $("robot-section");
  section.hidden = !r;
  if (!r) return;
  section.dataset.state = r.state;
  section.dataset.atReference = String(r.at_reference);
  $("robot-state").textContent = stateText(r, s);
  const read = r.read_at ? ` (read ${clock(new Date(r.read_at))})` : "";
  const before = r.state === "in_session" || r.state === "busy" ? "before the session: " : "";
  $("robot-pose").textContent = r.commanded_joints_deg
    ? `${before}joints ${joints(r.joints_deg)}°${read}; reference ${joints(r.reference_joints_deg)}°`
    : "";
  updateRobotControls();
}

export function updateRobotControls() {
  const r = page.station?.robot;
  const show = Boolean(r && r.at_reference === false && !page.running && r.state === "idle");
  $("to-reference").hidden = !show;
  $("to-reference").disabled = !(show && canAct());
  if (!show) $("to-reference-confirm").hidden = true;
  for (const id of ["to-reference-yes", "to-reference-no"]) $(id).disabled = !canAct();
}

async function toReference() {
  $("to-reference-confirm").hidden = true;
  $("robot-message").textContent = "moving to the reference pose…";
  try {
    const reply = await api("POST", "/station/robot/to-reference", undefined, { timeoutMs: 300000 });
    const moves = Array.isArray(reply?.moves) ? reply.moves.length : null;
    const final = reply?.final_joints_deg || reply?.joints_deg || reply?.pose?.joints_deg || reply?.final_pose?.joints_deg;
    $("robot-message").textContent = `at the reference pose${moves !== null ? ` after ${moves} move${moves === 1 ? "" : "s"}` : ""}${final ? `: joints ${joints(final)}°` : ""}`;
  } catch (e) {
    $("robot-message").textContent = `not moved: ${e.message}`;
  }
  refresh();
}

export function setUpStation(refreshFn) {
  refresh = refreshFn;
  $("to-reference").addEventListener("click", () => {
    $("to-reference-confirm").hidden = false;
    $("to-reference-no").focus();
  });
  $("to-reference-yes").addEventListener("click", toReference);
  $("to-reference-no").addEventListener("click", () => {
    $("to-reference-confirm").hidden = true;
    $("to-reference").focus();
  });
}
