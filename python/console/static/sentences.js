// Caretaker operator view: values and sentences as an operator reads them, shared by the run view.
// Loaded after app.js (its `element`) and before run_view.js; plain JS, no build step.
"use strict";

// ---- values and sentences --------------------------------------------------------------------
// A value as an operator reads it, by pride.phrasing's rules (the report and the terminal read the
// same): lengths (x, y, z) in mm, angles (roll, pitch, yaw, joints) in degrees, a 6-number pose as
// position/orientation, a value already in mm or degrees (a name ending _mm or _deg) rounded as
// those, other reals to 4 significant digits. ``name``: the value's id, which says what it measures.
const LENGTHS = ["x", "y", "z"];
const ANGLES = ["roll", "pitch", "yaw"];
const SIGNIFICANT = 4;

function kindOf(name) {
  if (LENGTHS.includes(name)) return "length";
  if (ANGLES.includes(name)) return "angle";
  return name.endsWith("_mm") ? "millimetres" : name.endsWith("_deg") ? "degrees" : null;
}

function fixed(value, decimals) {
  let text = value.toFixed(decimals);
  if (text.includes(".")) text = text.replace(/0+$/, "").replace(/\.$/, "");
  return text === "-0" ? "0" : text;
}

function numberText(value, kind) {
  if (kind === "length" || kind === "millimetres") {
    const millimetres = kind === "length" ? value * 1000 : value;
    return fixed(millimetres, Math.abs(millimetres) < 10 ? 1 : 0);
  }
  if (kind === "angle" || kind === "degrees") return fixed(kind === "angle" ? value * 180 / Math.PI : value, 1);
  if (!Number.isFinite(value) || value === 0) return fixed(value, 0);
  if (Math.abs(value) < 10 ** -SIGNIFICANT) return value.toExponential(1).replace(/e([+-])(\d)$/, "e$10$2");
  const whole = Math.floor(Math.log10(Math.abs(value))) + 1;
  return fixed(value, Math.min(SIGNIFICANT, Math.max(0, SIGNIFICANT - whole)));
}

function unitOf(kind) {
  return kind === "length" ? " mm" : kind === "angle" ? "°" : "";
}

function group(word, numbers, kind) {
  const texts = numbers.map((number) => numberText(number, kind));
  return `${word} ${texts.every((t) => t === "0") ? "0" : `(${texts.join(", ")})`}${unitOf(kind)}`;
}

function formatValue(value, name = "") {
  const kind = kindOf(name);
  if (typeof value === "boolean") return value ? "true" : "false";
  if (typeof value === "number") return Number.isInteger(value) && !kind ? String(value) : numberText(value, kind) + unitOf(kind);
  if (Array.isArray(value)) {
    if (!value.every((v) => typeof v === "number")) return `(${value.map((v) => formatValue(v)).join(", ")})`;
    if (value.length === 6 && name.endsWith("pose")) {
      return `${group("position", value.slice(0, 3), "length")}, ${group("orientation", value.slice(3), "angle")}`;
    }
    const of = kind || (name.includes("joint") ? "angle" : null);
    return `(${value.map((v) => numberText(v, of)).join(", ")})${unitOf(of)}`;
  }
  if (value === null || value === undefined) return "—";
  if (typeof value === "object") return Object.entries(value).map(([k, v]) => `${k.replaceAll("_", " ")} ${formatValue(v, k)}`).join(", ");
  return String(value);
}

function frameOf(number) {
  const cut = number.lastIndexOf("/");
  return cut < 0 ? "" : number.slice(0, cut + 1);
}

function lookup(env, ref) {
  const [name, field] = ref.split(".");
  if (!env || !(name in env)) return undefined;
  const value = env[name];
  if (field === undefined) return value;
  return value && typeof value === "object" && field in value ? value[field] : undefined;
}

// A sentence with its ${...} filled in where the run knows them, marked as still unknown where not.
function fillSentence(node, parts, env) {
  node.replaceChildren(...parts.map((part) => {
    if (part.ref === undefined) return document.createTextNode(part.text);
    const value = lookup(env, part.ref);
    if (value === undefined) {
      const unknown = element("var", "unknown", `‹${part.ref}›`);
      unknown.title = `${part.ref}: known once the run has it`;
      return unknown;
    }
    const known = element("span", "value", formatValue(value, part.ref.split(".").pop()));
    known.title = part.ref;
    return known;
  }));
}

function sentenceOf(number) {
  const item = instructionItem(number);
  const text = item && item.querySelector(":scope > .line > .text");
  return text ? text.textContent : "";
}

function instructionItem(number) {
  return number ? document.querySelector(`#procedure li.instruction[data-number="${CSS.escape(number)}"]`) : null;
}
