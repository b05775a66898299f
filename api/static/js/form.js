// The start form. The Kind list is the station's (GET /station's plans, calibration included); each
// plan's parameters are fields generated from its JSON schema (GET /plans): defaults shown, each value
// checked as it is typed with the message beside its field, the service's refusal mapped back onto the
// fields it names. The raw JSON (only what differs from the defaults) stays available and in step.

import { ApiError } from "./api.js";
import { page } from "./state.js";
import { $, el } from "./util.js";

let fields = []; // {name, prop, kind: "number"|"integer"|"enum"|"boolean"|"string"|"json", input, error}
let editingRaw = false;

/** The schema of a value, without the null branch of an optional one: [schema, nullable]. */
function base(prop) {
  if (Array.isArray(prop.anyOf)) {
    const rest = prop.anyOf.filter((s) => s.type !== "null");
    return [rest.length === 1 ? { ...rest[0], ...strip(prop) } : { ...strip(prop), type: "json" }, rest.length < prop.anyOf.length];
  }
  return [prop, false];
}

const strip = (prop) => ({ title: prop.title, description: prop.description, default: prop.default });

function kindOf(schema) {
  if (Array.isArray(schema.enum)) return "enum";
  if (schema.type === "integer") return "integer";
  if (schema.type === "number") return "number";
  if (schema.type === "boolean") return "boolean";
  if (schema.type === "string") return "string";
  return "json";
}

const UNITS = { um: "µm", mm: "mm", deg: "°", s: "s", pct: "%", in: "in", kg: "kg", px: "px" };

/** A parameter's name as a label: "approach_um" -> "Approach (µm)". */
function labelOf(name) {
  const words = name.split("_");
  const unit = words.length > 1 ? UNITS[words[words.length - 1]] : undefined;
  if (unit) words.pop();
  const text = words.join(" ");
  return `${text[0].toUpperCase()}${text.slice(1)}${unit ? ` (${unit})` : ""}`;
}

const shownDefault = (v) => (v === undefined ? "" : v === null ? "none" : typeof v === "object" ? JSON.stringify(v) : String(v));

function makeField(name, prop, required) {
  const [schema, nullable] = base(prop);
  const kind = kindOf(schema);
  const id = `param-${name}`;
  let input;
  if (kind === "enum") {
    input = el("select", { id, name }, ...schema.enum.map((v) => el("option", { value: String(v) }, String(v))));
  } else if (kind === "boolean") {
    input = el("input", { id, name, type: "checkbox" });
  } else if (kind === "number" || kind === "integer") {
    input = el("input", { id, name, type: "number", step: kind === "integer" ? "1" : "any", inputMode: "decimal" });
    if (schema.minimum !== undefined) input.min = String(schema.minimum);
    if (schema.maximum !== undefined) input.max = String(schema.maximum);
  } else {
    input = el("input", { id, name, type: "text", spellcheck: false, className: kind === "json" ? "mono" : "" });
  }
  if (nullable || kind === "json") input.placeholder = nullable ? `default: ${shownDefault(prop.default)}` : "";
  const error = el("span", { className: "error field-error", id: `${id}-error`, role: "alert" });
  input.setAttribute("aria-describedby", `${id}-help ${id}-error`);
  const bits = [];
  if (schema.description) bits.push(schema.description);
  if (required) bits.push("required");
  else bits.push(`default: ${shownDefault(prop.default)}`);
  if (kind === "json") bits.push("JSON");
  const help = el("span", { className: "muted help", id: `${id}-help` }, bits.join("; "));
  const label = el("label", { for: id }, `${labelOf(name)} `, el("code", {}, name));
  const row = el("div", { className: "field" }, label, input, help, error);
  const f = { name, prop, schema, nullable, required, kind, input, error, row };
  setValue(f, prop.default);
  input.addEventListener(kind === "enum" || kind === "boolean" ? "change" : "input", () => {
    check(f);
    if (!editingRaw) writeRaw();
  });
  return f;
}

function setValue(f, v) {
  if (f.kind === "boolean") f.input.checked = Boolean(v);
  else if (v === undefined || v === null) f.input.value = "";
  else if (f.kind === "json") f.input.value = JSON.stringify(v);
  else f.input.value = String(v);
}

/** The field's value: {value} when set and different from the default, {} when left at it, {error}. */
function read(f) {
  const raw = f.kind === "boolean" ? f.input.checked : f.input.value.trim();
  if (raw === "" && f.kind !== "boolean") return f.required ? { error: "required" } : {};
  let value = raw;
  if (f.kind === "number" || f.kind === "integer") {
    value = Number(raw);
    if (!Number.isFinite(value)) return { error: `"${raw}" is not a number` };
    if (f.kind === "integer" && !Number.isInteger(value)) return { error: "must be a whole number" };
    const s = f.schema;
    if (s.minimum !== undefined && value < s.minimum) return { error: `must be at least ${s.minimum}` };
    if (s.maximum !== undefined && value > s.maximum) return { error: `must be at most ${s.maximum}` };
    if (s.exclusiveMinimum !== undefined && value <= s.exclusiveMinimum) return { error: `must be above ${s.exclusiveMinimum}` };
    if (s.exclusiveMaximum !== undefined && value >= s.exclusiveMaximum) return { error: `must be below ${s.exclusiveMaximum}` };
  } else if (f.kind === "json") {
    try {
      value = JSON.parse(raw);
    } catch {
      return { error: "is not JSON (e.g. [1, 2] or {\"S1\": [[0, 30, 60, 0, 90, 0]]})" };
    }
  } else if (f.kind === "string" && f.schema.minLength && raw.length < f.schema.minLength) {
    return { error: `needs at least ${f.schema.minLength} characters` };
  }
  if (JSON.stringify(value) === JSON.stringify(f.prop.default)) return {};
  return { value };
}

function check(f) {
  const r = read(f);
  f.error.textContent = r.error ? `${f.name} ${r.error}` : "";
  f.input.setAttribute("aria-invalid", r.error ? "true" : "false");
  return r;
}

function writeRaw() {
  const out = {};
  for (const f of fields) {
    const r = read(f);
    if ("value" in r) out[f.name] = r.value;
  }
  $("params").value = JSON.stringify(out, null, 1).replace(/\n\s*/g, " ");
  $("params-error").textContent = "";
}

function readRaw() {
  editingRaw = true;
  try {
    const doc = JSON.parse($("params").value || "{}");
    if (typeof doc !== "object" || doc === null || Array.isArray(doc)) throw new Error("not an object");
    for (const f of fields) {
      setValue(f, f.name in doc ? doc[f.name] : f.prop.default);
      check(f);
    }
    const unknown = Object.keys(doc).filter((k) => !fields.some((f) => f.name === k));
    $("params-error").textContent = unknown.length ? `unknown parameter(s): ${unknown.join(", ")}` : "";
  } catch (e) {
    $("params-error").textContent = `the parameters are not a JSON object: ${e.message}`;
  } finally {
    editingRaw = false;
  }
}

/** Fill the form for the kind selected. */
export function showKind() {
  const kind = $("kind").value;
  const plan = page.plans.get(kind);
  $("start-error").textContent = "";
  if (!plan) {
    fields = [];
    $("param-fields").replaceChildren();
    $("kind-help").textContent = "";
    return;
  }
  const schema = plan.params_schema;
  const required = new Set(schema.required || []);
  fields = Object.entries(schema.properties || {}).map(([n, p]) => makeField(n, p, required.has(n)));
  const suggestion = suggestSession(kind);
  const session = fields.find((f) => f.name === "session");
  if (session && suggestion) session.input.value = suggestion;
  $("param-fields").replaceChildren(...fields.map((f) => f.row));
  const needs = plan.needs.length ? `drives the ${plan.needs.join(", ")}` : "no hardware: works on the record";
  $("kind-help").textContent = `${(schema.description || "").split("\n").join(" ")} (${needs})`;
  writeRaw();
}

/** A stored session a sweep or re-analysis could start from: the latest validation, or the latest. */
function suggestSession(kind) {
  const items = page.history || [];
  if (kind === "sweep") return items.find((s) => s.kind === "validation" && s.state === "succeeded")?.id;
  if (kind === "reanalyse") return items.find((s) => s.state === "succeeded")?.id;
  return undefined;
}

/** The Kind list from the station's plans. */
export function setKinds(names) {
  const select = $("kind");
  const have = [...select.options].map((o) => o.value);
  if (JSON.stringify(have) === JSON.stringify(names)) return;
  const before = select.value;
  select.replaceChildren(...names.map((n) => el("option", { value: n }, n)));
  if (names.includes(before)) select.value = before;
  showKind();
}

/** The parameters to start with, or null after saying what is wrong (beside each field). */
export function formParams() {
  let doc;
  try {
    doc = JSON.parse($("params").value || "{}");
  } catch (e) {
    $("params-error").textContent = `the parameters are not JSON: ${e.message}`;
    $("raw-json").open = true;
    return null;
  }
  let bad = false;
  for (const f of fields) if (check(f).error) bad = true;
  if (bad) {
    $("start-error").textContent = "check the fields marked below";
    return null;
  }
  return doc;
}

/** The service refused the parameters: its message at the top and each part beside the field it names. */
export function showRefusal(e) {
  $("start-error").textContent = e.message;
  if (!(e instanceof ApiError) || !e.message) return;
  const detail = e.message.replace(/^[a-z]+ parameters: /, "");
  for (const part of detail.split("; ")) {
    const m = /^([A-Za-z_][A-Za-z0-9_]*)(?:\.[^:]*)?: (.*)$/.exec(part);
    const f = m && fields.find((x) => x.name === m[1]);
    if (f) {
      f.error.textContent = `${f.name}: ${m[2]}`;
      f.input.setAttribute("aria-invalid", "true");
    }
  }
  if (Array.isArray(e.doc?.problems) && e.doc.problems.length) {
    $("start-error").textContent = `${e.message}\n${e.doc.problems.map((p) => `• ${p}`).join("\n")}`;
  }
}

export function setUpForm() {
  $("kind").addEventListener("change", showKind);
  $("params").addEventListener("input", readRaw);
}

export const formInputs = () => [$("kind"), $("params"), ...fields.map((f) => f.input)];
