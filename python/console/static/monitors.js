// Caretaker operator view: telemetry against its SysRep limits, and the run's monitors. Loaded after
// app.js (its `view`, `$`, `element`), sentences.js (`formatValue`) and run_view.js, which calls
// renderMonitors whenever it draws the run. Plain JS, no build step.
//
// A value with limits is green, yellow or red AND says so in words ("RED HIGH", as the server's
// console/monitor_states.py names it), so no state is told by colour alone.
"use strict";

const LIMIT_ICON = {green: "✓", yellow: "▲", red: "⚠"};

// A live reading's state against its limits, or null (no limits, no value, or a stale value).
function readingLimit(reading) {
  return reading && !reading.error && !reading.stale && reading.limit ? reading.limit : null;
}

// The words after a value: "YELLOW HIGH (yellow above 40)"; green says only GREEN.
function limitWords(limit) {
  return limit.state === "green" ? limit.words : `${limit.words} (${limit.limit})`;
}

// A telemetry value's text coloured by its limits, saying its state too: "Bench Temperature = 45 degC
// YELLOW HIGH (yellow above 40)"; uncoloured without limits (limit null).
function limitedValue(text, limit) {
  const node = element("span", "limit-value", limit ? `${limit.state === "green" ? "" : LIMIT_ICON[limit.state] + " "}${text} ${limitWords(limit)}` : text);
  node.dataset.limit = limit ? limit.state : "";
  return node;
}

// Texts and nodes with a separator between each two.
function joined(parts, separator = " · ") {
  return parts.flatMap((part, n) => (n ? [separator, part] : [part]));
}

// The step of the run's own procedure an instruction number is in ("2.1/1.3" is in step 2).
function mainStep(number) {
  return number ? Number(number.split("/")[0].split(".")[0]) : null;
}

// Which monitors are active and what counts of what they saw, as pride.monitoring's board has it: a
// step's while the run is in that step, a procedure-scoped one once its step was entered; a
// violation recorded before its monitor last became active, or before a resume, is over.
function monitorRows(state) {
  const monitors = view.procedure.monitors || [];
  const news = state.monitors || {seen: {}, entered: [], step: null, step_since: 0, resumed: 0};
  const live = Boolean(state.live) && state.status === "active";
  const step = mainStep(state.current) ?? news.step;
  const stepSince = step === news.step ? news.step_since : Infinity;  // arrived with nothing recorded there yet
  const entered = new Set([...news.entered, step]);
  return monitors.map((monitor) => {
    const active = live && (monitor.scope === "procedure" ? entered.has(monitor.step) : monitor.step === step);
    const seen = news.seen[monitor.name] || null;
    const since = Math.max(news.resumed, monitor.scope === "procedure" ? 0 : stepSince);
    return {monitor, active, seen, violated: Boolean(seen && seen.violated && seen.seq >= since && (active || !live))};
  }).filter((row) => row.active || row.seen);
}

// red: violated now (the record says so); yellow: the value is in its item's yellow (or red) band, or
// out of its monitor's test but not yet for its persistence; green: within; none: no live value.
function monitorState(row) {
  if (row.violated) return "red";
  const reading = view.telemetry.get(`${row.monitor.system}.${row.monitor.telemetry}`);
  if (!row.active || !reading || reading.error || reading.stale) return "none";
  const limit = readingLimit(reading);
  const out = row.monitor.check !== null && view.checks[row.monitor.check] === false;
  return out || (limit && limit.state !== "green") ? "yellow" : "green";
}

const MONITOR_WORDS = {red: "⚠ RED · violated", yellow: "▲ YELLOW", green: "✓ GREEN", none: "◌ no live value"};
const ACTION_WORDS = {hold: "the run held", halt: "the run halted"};  // what a recorded violation did

function renderMonitors() {
  const state = view.state;
  const monitors = (view.procedure && view.procedure.monitors) || [];
  $("monitors-panel").hidden = !state || !monitors.length;
  if (!state || !monitors.length) return;
  const list = $("monitors");
  const rows = monitorRows(state);
  list.replaceChildren(...rows.map(monitorItem));
  if (!rows.length) list.append(element("li", "monitor-none", state.live ? "No monitor is active now." : "No monitor saw anything in this run."));
}

function monitorItem(row) {
  const {monitor, seen} = row;
  const state = monitorState(row);
  const item = element("li", "monitor");
  item.dataset.monitor = monitor.name;
  item.dataset.state = state;
  item.dataset.active = String(row.active);
  const head = element("div", "monitor-head");
  const words = state === "none" && !row.active ? "◌ not active" : MONITOR_WORDS[state];
  head.append(element("span", "monitor-state", words), " ", element("span", "monitor-text", monitor.text));
  item.append(head);
  const reading = view.telemetry.get(`${monitor.system}.${monitor.telemetry}`);
  if (row.active) item.append(monitorValue(monitor, reading));
  const where = row.active ? `step ${monitor.step}${monitor.scope === "procedure" ? " on" : ""}` :
    view.state.live ? "not active now" : "the run is over";
  item.append(element("div", "monitor-meta", `${where} · when violated, ${monitor.on_violation}`));
  if (seen) item.append(element("div", "monitor-news", seenWords(seen)));
  return item;
}

// The monitored value, coloured by its item's limits and saying its state in words.
function monitorValue(monitor, reading) {
  const line = element("div", "monitor-value");
  const units = monitor.units ? ` ${monitor.units}` : "";
  if (!reading || reading.error) {
    line.textContent = `${monitor.label}: ${reading ? reading.error : "no value"}`;
    return line;
  }
  line.append(limitedValue(`${monitor.label} = ${formatValue(reading.value, reading.item)}${units}${reading.stale ? " · STALE" : ""}`,
    readingLimit(reading)));
  return line;
}

// What the record says the monitor saw last: "violated at 12:00:01 (1.2): 55 (red above 50) · the run held".
function seenWords(seen) {
  const when = `${new Date(seen.time).toLocaleTimeString()}${seen.instruction ? ` (${seen.instruction})` : ""}`;
  const times = seen.violations > 1 ? ` · violated ${seen.violations} times in this run` : "";
  if (!seen.violated) return `cleared at ${when}: ${formatValue(seen.value)}${times}`;
  const goto = seen.action.startsWith("goto:") ? seen.action.slice(5) : null;
  const step = goto && view.procedure.steps.find((s) => s.id === goto || String(s.number) === goto);
  const action = goto ? `the run went to ${step ? `${step.number}. ${step.title}` : goto}` : ACTION_WORDS[seen.action] || seen.action;
  return `violated at ${when}: ${formatValue(seen.value)} (${seen.limit}) · ${action}${times}`;
}
