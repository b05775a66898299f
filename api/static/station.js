// The operator page: a client of the station's API only. HTTP is the source of truth; the event stream
// (cookie-authenticated EventSource) says when to refetch, and a slow poll covers a lost stream.
"use strict";

const API = "/api/v1";
const FINAL = new Set(["stopped", "aborted", "failed", "succeeded", "interrupted"]);
const DEFAULT_PARAMS = {
  validation: "{}",
  repeatability: '{"cycles": 10}',
  sweep: '{"session": ""}',
  reanalyse: '{"session": ""}',
};
const $ = (id) => document.getElementById(id);

let current = null; // the session shown (id)
let shownPrompt = null; // the prompt id in the dialog
let refreshing = false;
let again = false;

async function api(method, path, body) {
  const init = { method, headers: {}, credentials: "same-origin" };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const r = await fetch(API + path, init);
  if (r.status === 204) return null;
  const type = r.headers.get("content-type") || "";
  const doc = type.includes("json") ? await r.json() : await r.text();
  if (!r.ok) {
    if (r.status === 401) $("auth-note").hidden = false;
    const err = new Error((doc && doc.detail) || `${r.status} ${r.statusText}`);
    err.status = r.status;
    throw err;
  }
  return doc;
}

function say(text) {
  $("message").textContent = text || "";
}

function fmt(v, digits = 4) {
  return typeof v === "number" ? v.toFixed(digits) : String(v ?? "");
}

// ------------------------------------------------------------------ station and sessions

async function loadStation() {
  const s = await api("GET", "/station");
  $("station-name").textContent = s.name;
  $("devices").replaceChildren(
    ...Object.entries(s.devices).map(([name, d]) => {
      const span = document.createElement("span");
      span.textContent = `${name}: ${d.identity.model || "?"} (${d.state})`;
      return span;
    }),
  );
  return s;
}

async function refresh() {
  if (refreshing) {
    again = true;
    return;
  }
  refreshing = true;
  try {
    const station = await loadStation();
    const list = await api("GET", "/sessions?limit=20");
    renderHistory(list.items);
    const running = station.session ? station.session.id : null;
    if (running) current = running;
    else if (!current && list.items.length) current = list.items[0].id;
    if (current) await showSession(current);
    await showPrompt();
    updateLive(running);
  } catch (e) {
    say(e.message);
  } finally {
    refreshing = false;
    if (again) {
      again = false;
      refresh();
    }
  }
}

async function showSession(id) {
  const s = await api("GET", `/sessions/${id}`);
  $("current").hidden = false;
  $("session-id").textContent = s.id;
  $("session-kind").textContent = s.kind;
  $("state").textContent = s.state;
  $("state").dataset.state = s.state;
  const p = s.progress;
  $("progress").max = Math.max(p.total, 1);
  $("progress").value = p.done;
  $("progress-text").textContent =
    `${p.done} / ${p.total} steps` + (p.eta_s != null && !FINAL.has(s.state) ? `, about ${Math.round(p.eta_s)} s left` : "");
  $("session-error").textContent = s.error || "";
  const active = !FINAL.has(s.state);
  $("pause").disabled = !(s.state === "running" || s.state === "awaiting_operator");
  $("resume").disabled = !(s.state === "paused" || s.state === "pausing" || s.state === "interrupted");
  $("stop").disabled = !active;
  $("abort").disabled = !active;
  $("start").disabled = active;
  if (FINAL.has(s.state)) await showResults(s);
  else $("results-section").hidden = true;
}

function renderHistory(items) {
  const body = $("sessions").querySelector("tbody");
  body.replaceChildren(
    ...items.map((s) => {
      const tr = document.createElement("tr");
      tr.dataset.id = s.id;
      for (const text of [s.id, s.kind, s.state, s.created_at.replace("T", " ").slice(0, 19)]) {
        const td = document.createElement("td");
        td.textContent = text;
        tr.append(td);
      }
      const td = document.createElement("td");
      if (FINAL.has(s.state)) {
        const a = document.createElement("a");
        a.href = `${API}/sessions/${s.id}/report.html`;
        a.textContent = "report";
        a.target = "_blank";
        td.append(a);
      }
      tr.append(td);
      tr.addEventListener("click", (ev) => {
        if (ev.target.tagName === "A") return;
        current = s.id;
        refresh();
      });
      return tr;
    }),
  );
}

// ------------------------------------------------------------------ results

let resultsShown = null;

async function showResults(s) {
  const key = `${s.id}:${s.updated_at}`;
  if (resultsShown === key) return;
  resultsShown = key;
  $("results-section").hidden = false;
  const r = s.results || {};
  const rows = [];
  if (s.kind === "validation") {
    for (const k of ["mean_um", "max_um", "parallelogram_mean_um", "parallelogram_max_um", "scale"]) {
      if (k in r) rows.push([k, fmt(r[k], 3)]);
    }
  } else if (s.kind === "repeatability") {
    for (const [test, rp] of Object.entries(r.rp_mm || {})) rows.push([`RP ${test} (mm)`, fmt(rp, 5)]);
    if ("n_cycles" in r) rows.push(["cycles", r.n_cycles]);
  } else {
    for (const [k, v] of Object.entries(r)) if (typeof v !== "object") rows.push([k, fmt(v, 4)]);
  }
  const table = document.createElement("table");
  table.id = "results-table";
  for (const [k, v] of rows) {
    const tr = table.insertRow();
    tr.insertCell().textContent = k;
    tr.insertCell().textContent = v;
  }
  if (s.kind === "validation" && Array.isArray(r.positions)) {
    const positions = document.createElement("table");
    positions.id = "positions-table";
    const head = positions.insertRow();
    for (const h of ["#", "commanded (um)", "measured (um)"]) head.insertCell().textContent = h;
    r.positions.forEach((p, i) => {
      const tr = positions.insertRow();
      tr.insertCell().textContent = i + 1;
      tr.insertCell().textContent = (p.commanded_um || []).map((v) => fmt(v, 1)).join(", ");
      tr.insertCell().textContent = (p.measured_um || []).map((v) => fmt(v, 2)).join(", ");
    });
    $("results").replaceChildren(table, positions);
  } else {
    $("results").replaceChildren(table);
  }
  $("figures").replaceChildren();
  $("report-links").replaceChildren();
  if (!rows.length) return;
  try {
    const figs = await api("GET", `/sessions/${s.id}/figures`);
    $("figures").replaceChildren(
      ...figs.figures
        .filter((n) => n.endsWith(".png"))
        .map((n) => {
          const img = document.createElement("img");
          img.src = `${API}/sessions/${s.id}/figures/${n}`;
          img.alt = n;
          return img;
        }),
    );
  } catch (e) {
    say(e.message);
  }
  for (const [href, text] of [
    [`${API}/sessions/${s.id}/report.html`, "HTML report"],
    [`${API}/sessions/${s.id}/results?format=csv`, "table (CSV)"],
    [`${API}/sessions/${s.id}/export.zip`, "export (zip)"],
  ]) {
    const a = document.createElement("a");
    a.href = href;
    a.textContent = text;
    a.target = "_blank";
    $("report-links").append(a, " ");
  }
}

// ------------------------------------------------------------------ live view

let liveTimer = null;

function updateLive(running) {
  const src = running ? `${API}/sessions/${running}/latest.png` : `${API}/camera/snapshot.png?overlay=true`;
  const img = $("live");
  const next = `${src}${src.includes("?") ? "&" : "?"}t=${Date.now()}`;
  const probe = new Image();
  probe.onload = () => {
    img.src = probe.src;
    $("live-caption").textContent = running
      ? "the session's latest capture and its measurement"
      : "the camera now, with the measurement";
  };
  probe.onerror = () => {
    $("live-caption").textContent = running ? "waiting for the session's first capture" : "no camera view";
  };
  probe.src = next;
}

// ------------------------------------------------------------------ operator prompt

async function showPrompt() {
  const p = await api("GET", "/prompt");
  const dialog = $("prompt-dialog");
  if (!p) {
    if (dialog.open) dialog.close();
    shownPrompt = null;
    return;
  }
  if (shownPrompt === p.id && dialog.open) return;
  shownPrompt = p.id;
  $("prompt-message").textContent = p.message;
  $("prompt-error").textContent = "";
  $("prompt-fields").replaceChildren(
    ...p.fields.map((f) => {
      const label = document.createElement("label");
      label.textContent = `${f.label} (${f.unit}) `;
      const input = document.createElement("input");
      input.type = "number";
      input.step = "0.0001";
      input.name = f.name;
      input.value = f.requested != null ? f.requested.toFixed(4) : "";
      label.append(input);
      return label;
    }),
  );
  dialog.dataset.promptId = p.id;
  if (!dialog.open) dialog.showModal();
}

async function confirmPrompt(ev) {
  ev.preventDefault();
  const id = $("prompt-dialog").dataset.promptId;
  const readings = {};
  for (const input of $("prompt-fields").querySelectorAll("input")) {
    if (input.value !== "") readings[input.name] = Number(input.value);
  }
  try {
    await api("POST", `/prompt/${id}/confirm`, { readings });
    $("prompt-dialog").close();
    shownPrompt = null;
  } catch (e) {
    $("prompt-error").textContent = e.message;
  }
  refresh();
}

async function cancelPrompt() {
  const id = $("prompt-dialog").dataset.promptId;
  try {
    await api("POST", `/prompt/${id}/cancel`, { reason: "cancelled in the operator page" });
  } catch (e) {
    say(e.message);
  }
  $("prompt-dialog").close();
  shownPrompt = null;
  refresh();
}

// ------------------------------------------------------------------ actions

async function start(ev) {
  ev.preventDefault();
  let params;
  try {
    params = JSON.parse($("params").value || "{}");
  } catch (e) {
    say(`the parameters are not JSON: ${e.message}`);
    return;
  }
  try {
    const s = await api("POST", "/sessions", { kind: $("kind").value, params });
    current = s.id;
    resultsShown = null;
    say("");
  } catch (e) {
    say(e.message);
  }
  refresh();
}

async function act(action) {
  if (!current) return;
  if (action === "abort" && !window.confirm("Abort the session? The arm stops now.")) return;
  try {
    await api("POST", `/sessions/${current}/actions`, { action });
    say("");
  } catch (e) {
    say(e.message);
  }
  refresh();
}

function listen() {
  const source = new EventSource(`${API}/events`);
  source.onmessage = () => refresh();
  for (const kind of ["state", "step_finished", "prompt_raised", "prompt_answered", "image_captured", "error"]) {
    source.addEventListener(kind, () => refresh());
  }
  source.onerror = () => {
    // the browser reconnects by itself with Last-Event-ID; the poll below keeps the page right meanwhile
  };
}

document.addEventListener("DOMContentLoaded", () => {
  $("kind").addEventListener("change", () => {
    $("params").value = DEFAULT_PARAMS[$("kind").value];
  });
  $("start-form").addEventListener("submit", start);
  for (const action of ["pause", "resume", "stop", "abort"]) {
    $(action).addEventListener("click", () => act(action));
  }
  $("prompt-form").addEventListener("submit", confirmPrompt);
  $("prompt-cancel").addEventListener("click", cancelPrompt);
  $("prompt-dialog").addEventListener("cancel", (ev) => ev.preventDefault()); // Escape does not answer
  refresh();
  listen();
  setInterval(refresh, 2000);
});
