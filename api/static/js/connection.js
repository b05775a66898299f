// Connection state: the page knows when the service is unreachable (its event stream drops, or a request
// finds nobody, and a status poll fails) and says so within seconds: a banner "service unreachable since
// HH:MM:SS" (an aria-live region), every control greyed, the session's state unknown. It retries every
// second; once the service answers it re-reads everything and clears the banner.

import { alive } from "./api.js";
import { page } from "./state.js";
import { $, clock } from "./util.js";

const RETRY_MS = 1000;
let since = null;
let checking = false;
let retryTimer = null;
const listeners = { lost: [], restored: [] };

export function onConnection(kind, fn) {
  listeners[kind].push(fn);
}

function emit(kind) {
  for (const fn of listeners[kind]) fn();
}

/** Something failed to reach the service: check now (a failed status poll means it is lost). */
export async function suspect() {
  if (page.connection === "lost" || checking) return;
  checking = true;
  try {
    if (!(await alive())) lost();
  } finally {
    checking = false;
  }
}

function lost() {
  if (page.connection === "lost") return;
  page.connection = "lost";
  since = new Date();
  document.body.dataset.connection = "lost";
  const banner = $("connection-banner");
  banner.textContent = `service unreachable since ${clock(since)}: the session's state is unknown until it answers again (retrying every second)`;
  banner.hidden = false;
  emit("lost");
  retryTimer = setInterval(retry, RETRY_MS);
}

async function retry() {
  if (checking) return;
  checking = true;
  try {
    if (await alive()) restored();
  } finally {
    checking = false;
  }
}

function restored() {
  clearInterval(retryTimer);
  retryTimer = null;
  page.connection = "ok";
  document.body.dataset.connection = "ok";
  $("connection-banner").hidden = true;
  $("connection-banner").textContent = "";
  emit("restored");
}
