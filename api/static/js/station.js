// The station: its devices in the header, and the robot's state and pose from the start (the service
// reads it between sessions), with "Move to the reference pose" whenever the arm is not at it.

import { api } from "./api.js";
import { canAct, mayMove, page } from "./state.js";
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
  const latched = typeof r.latched === "string" && r.latched !== "" && r.state === "idle";
  $("latch").hidden = !latched;
  section.dataset.latched = String(latched);
  if (latched) {
    $("latch-text").replaceChildren(
      el("strong", {}, "A stop is latched: the arm moves for nothing until it is acknowledged. "),
      `It was: ${r.latched}. Look at the arm and the cell first.`,
    );
  }
  const read = r.read_at ? ` (read ${clock(new Date(r.read_at))})` : "";
  const before = r.state === "in_session" || r.state === "busy" ? "before the session: " : "";
  $("robot-pose").textContent = r.commanded_joints_deg
    ? `${before}joints ${joints(r.joints_deg)}°${read}; reference ${joints(r.reference_joints_deg)}°`
    : "";
  // the latest controller self-test of this robot (a selftest session), until its identity changes
  const t = s.selftest;
  section.dataset.selftest = t ? String(t.passed) : "missing";
  $("robot-selftest").textContent = t
    ? `self-test ${t.passed ? "passed" : "NOT passed: see its session, then run it again"} (session ${t.session_id}${t.when ? `, ${new Date(t.when).toLocaleString()}` : ""})`
    : "no self-test of this controller yet: run one (kind selftest, or station run selftest)";
  updateRobotControls();
}

export function updateRobotControls() {
  const r = page.station?.robot;
  const latched = Boolean(r && typeof r.latched === "string" && r.latched !== "");
  const local = page.access?.local === true;
  $("acknowledge").disabled = !(canAct() && local && !page.running);
  $("latch-remote").hidden = local;
  const show = Boolean(r && r.at_reference === false && !page.running && r.state === "idle" && !latched);
  $("to-reference").hidden = !show;
  $("to-reference").disabled = !(show && canAct() && mayMove());
  if (!show) $("to-reference-confirm").hidden = true;
  $("to-reference-no").disabled = !canAct();
  // Move now only once the route is read and refuses nothing
  $("to-reference-yes").disabled = !(canAct() && $("to-reference-route").dataset.route === "ok");
}

/** The route GET /station/robot plans from where the arm is: its moves, or every problem the driver's
 * checks find in it (then nothing can be sent: Move now stays off). */
function showRoute(arm) {
  const route = arm.route || { moves: [], problems: [] };
  const box = $("to-reference-route");
  const yes = $("to-reference-yes");
  if (route.problems.length) {
    box.dataset.route = "refused";
    box.replaceChildren(
      el("p", { className: "error" }, `The route is refused by the driver's checks; nothing would move (${route.problems.length} problem${route.problems.length === 1 ? "" : "s"}):`),
      el("ul", { id: "to-reference-problems" }, ...route.problems.map((p) => el("li", {}, p))),
      el("p", {}, "Jog the arm clear with the pendant (the route goes up through the lift pose), then try again."),
    );
    yes.disabled = true;
    return;
  }
  const n = route.moves.length;
  box.dataset.route = n ? "ok" : "none";
  if (!n) {
    box.replaceChildren(el("p", {}, "The arm is already at its reference pose: nothing to move."));
    yes.disabled = true;
    return;
  }
  box.replaceChildren(
    el("p", {}, `From joints ${joints(arm.position?.commanded_joints_deg)}°: ${n} move${n === 1 ? "" : "s"}${route.via_lift ? ", up through the lift pose (upper arm and forearm upright), across and down" : ", direct"}, each within the driver's joint step:`),
    el("ol", { id: "to-reference-moves", className: "mono" }, ...route.moves.map((q) => el("li", {}, `${joints(q)}°`))),
  );
  yes.disabled = !canAct();
}

async function offerRoute() {
  $("to-reference-confirm").hidden = false;
  $("to-reference-yes").disabled = true;
  $("to-reference-route").dataset.route = "reading";
  $("to-reference-route").replaceChildren(el("p", { className: "muted" }, "reading the route from where the arm is…"));
  $("to-reference-no").focus();
  try {
    showRoute(await api("GET", "/station/robot"));
  } catch (e) {
    $("to-reference-route").dataset.route = "unknown";
    $("to-reference-route").replaceChildren(el("p", { className: "error" }, `The route cannot be read: ${e.message}`));
  }
}

async function toReference() {
  $("to-reference-confirm").hidden = true;
  $("to-reference").disabled = true;
  $("robot-message").textContent = "moving to the reference pose…";
  page.moving = true;
  try {
    const reply = await api("POST", "/station/robot/to-reference", undefined, { timeoutMs: 600000 });
    const moves = Array.isArray(reply?.moves) ? reply.moves.length : null;
    const final = reply?.final_pose?.joints_deg;
    $("robot-message").textContent = `at the reference pose${moves !== null ? ` after ${moves} move${moves === 1 ? "" : "s"}` : ""}${final ? `: joints ${joints(final)}°` : ""}`;
  } catch (e) {
    const problems = Array.isArray(e.doc?.problems) ? ` (${e.doc.problems.join("; ")})` : "";
    $("robot-message").textContent = `not moved to the reference pose: ${e.message}${problems}`;
  } finally {
    page.moving = false;
  }
  refresh();
}

async function acknowledge() {
  $("acknowledge").disabled = true;
  try {
    const reply = await api("POST", "/station/robot/acknowledge");
    $("robot-message").textContent = reply?.acknowledged
      ? `stop acknowledged at the station (it was: ${reply.reason}); the arm may move again`
      : "no stop was latched";
  } catch (e) {
    $("robot-message").textContent = `the stop is still latched: ${e.message}`;
  }
  refresh();
}

export function setUpStation(refreshFn) {
  refresh = refreshFn;
  $("acknowledge").addEventListener("click", acknowledge);
  $("to-reference").addEventListener("click", offerRoute);
  $("to-reference-yes").addEventListener("click", toReference);
  $("to-reference-no").addEventListener("click", () => {
    $("to-reference-confirm").hidden = true;
    $("to-reference").focus();
  });
}
