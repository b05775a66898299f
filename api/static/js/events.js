// The station's event stream (GET /events, Server-Sent Events; the cookie carries the token). An event
// is a hint to re-read over HTTP. The browser reconnects by itself, sending Last-Event-ID, so nothing is
// missed across a restart of the service; a stream the service refused is opened again once it answers.

import { API } from "./api.js";
import { suspect } from "./connection.js";

const TYPES = [
  "state",
  "step_started",
  "step_finished",
  "prompt_raised",
  "prompt_answered",
  "image_captured",
  "measurement",
  "preflight",
  "resumed",
  "connected",
  "position",
  "returned",
  "warning",
  "error",
  "scale_calibration",
  "abandoned",
];

let source = null;
const handlers = [];

/** Call fn(type, event) for every event ({id, session_id, seq, time, type, data}). */
export function onEvent(fn) {
  handlers.push(fn);
}

function dispatch(type, message) {
  let doc;
  try {
    doc = JSON.parse(message.data);
  } catch {
    return;
  }
  for (const fn of handlers) fn(type, doc);
}

/** Open the stream unless it is open or reconnecting. */
export function openEvents() {
  if (source !== null && source.readyState !== EventSource.CLOSED) return;
  source = new EventSource(`${API}/events`);
  for (const type of TYPES) source.addEventListener(type, (m) => dispatch(type, m));
  source.onerror = () => {
    // connection refused or dropped: the browser retries with Last-Event-ID; meanwhile check the service
    suspect();
  };
}

/** Whether the stream is open (or reconnecting by itself). */
export const eventsOpen = () => source !== null && source.readyState !== EventSource.CLOSED;
