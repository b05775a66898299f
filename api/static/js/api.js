// The API client: one fetch wrapper. A refusal is an ApiError carrying the problem's detail and code; a
// service that does not answer is Unreachable (the connection module then checks and says so).

export const API = "/api/v1";

export class ApiError extends Error {
  constructor(status, doc) {
    super((doc && doc.detail) || `${status}`);
    this.status = status;
    this.code = doc && doc.code;
    this.doc = doc;
  }
}

export class Unreachable extends Error {}

let onUnreachable = () => {};
let onUnauthorized = () => {};

/** Who hears of a request that found no service, and of a 401 (the token changed or expired). */
export function watch({ unreachable, unauthorized }) {
  onUnreachable = unreachable;
  onUnauthorized = unauthorized;
}

async function send(path, init, timeoutMs) {
  const control = new AbortController();
  const timer = setTimeout(() => control.abort(), timeoutMs);
  try {
    return await fetch(API + path, { ...init, credentials: "same-origin", signal: control.signal });
  } catch (e) {
    onUnreachable();
    throw new Unreachable(`the service did not answer (${e.name === "AbortError" ? "timed out" : e.message})`);
  } finally {
    clearTimeout(timer);
  }
}

async function refusal(r) {
  const type = r.headers.get("content-type") || "";
  const doc = type.includes("json") ? await r.json() : { detail: await r.text() };
  if (r.status === 401) onUnauthorized();
  return new ApiError(r.status, doc);
}

/** A JSON request: the parsed body, null for 204. */
export async function api(method, path, body, { timeoutMs = 30000 } = {}) {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const r = await send(path, init, timeoutMs);
  if (r.status === 204) return null;
  if (!r.ok) throw await refusal(r);
  return r.json();
}

/** An image: {url (an object URL: revoke it when replaced), headers}. */
export async function image(path, { timeoutMs = 30000 } = {}) {
  const r = await send(path, { method: "GET" }, timeoutMs);
  if (!r.ok) throw await refusal(r);
  return { url: URL.createObjectURL(await r.blob()), headers: r.headers };
}

/** Whether the service answers at all (GET /health, no token), within `timeoutMs`. */
export async function alive(timeoutMs = 2000) {
  const control = new AbortController();
  const timer = setTimeout(() => control.abort(), timeoutMs);
  try {
    const r = await fetch(`${API}/health`, { signal: control.signal, cache: "no-store" });
    return r.ok;
  } catch {
    return false;
  } finally {
    clearTimeout(timer);
  }
}
