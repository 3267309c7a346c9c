// Caretaker operator view. Plain JS, no build step, nothing loaded from elsewhere.
//
// The server is the authority: this page draws what /api/runs/ID and the run's WebSocket say
// and sends every action to /api/runs/ID/actions, where the executive accepts or refuses it
// (observers are refused there too; disabled buttons are only a courtesy).
"use strict";

const $ = (id) => document.getElementById(id);

const view = {
  me: null,            // {user, name, role, may_act}
  runId: null,
  procedure: null,     // procedure JSON (steps, instructions)
  state: null,         // run state JSON (executive snapshot + per-instruction details)
  events: [],          // audit events seen so far
  telemetry: new Map(),// "system.item" -> {value, age, stale, receivedAt}
  socket: null,
  reconnectTimer: null,
  lastImageSeq: null,
};

// ---- server calls ----------------------------------------------------------------------------
async function api(method, path, body) {
  const response = await fetch(path, {
    method,
    headers: body === undefined ? {} : {"Content-Type": "application/json"},
    body: body === undefined ? undefined : JSON.stringify(body),
  });
  const data = await response.json().catch(() => ({}));
  if (!response.ok) {
    const error = new Error(data.error || `${response.status} ${response.statusText}`);
    error.status = response.status;
    throw error;
  }
  return data;
}

async function act(action, extra = {}) {
  $("action-error").textContent = "";
  try {
    await api("POST", `/api/runs/${encodeURIComponent(view.runId)}/actions`, {action, ...extra});
  } catch (error) {
    $("action-error").textContent = error.message;
  }
}

// ---- sign-in ---------------------------------------------------------------------------------
async function loadSession() {
  try {
    view.me = await api("GET", "/api/session");
  } catch (error) {
    view.me = null;
  }
  $("sign-in-view").hidden = view.me !== null;
  $("main-view").hidden = view.me === null;
  $("sign-out").hidden = view.me === null;
  $("who").textContent = view.me ? `${view.me.user} (${view.me.role})` : "";
  document.body.dataset.role = view.me ? view.me.role : "";
  if (view.me) {
    $("start-panel").hidden = !view.me.may_act;
    await Promise.all([loadCatalog(), loadRuns()]);
    openRunFromHash();
  }
}

$("sign-in-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  $("sign-in-error").textContent = "";
  try {
    await api("POST", "/api/session", {user: $("user-id").value.trim()});
    await loadSession();
  } catch (error) {
    $("sign-in-error").textContent = error.message;
  }
});

$("sign-out").addEventListener("click", async () => {
  await api("DELETE", "/api/session");
  closeSocket();
  location.hash = "";
  await loadSession();
});

// ---- catalog and runs ------------------------------------------------------------------------
function fillSelect(select, names) {
  select.replaceChildren(...names.map((name) => new Option(name, name)));
}

async function loadCatalog() {
  const catalog = await api("GET", "/api/catalog");
  fillSelect($("start-procedure"), catalog.procedures);
  fillSelect($("start-binding"), catalog.bindings);
}

async function loadRuns() {
  const {runs} = await api("GET", "/api/runs");
  $("run-list").replaceChildren(...runs.map((run) => {
    const item = document.createElement("li");
    item.dataset.runId = run.run_id;
    const open = document.createElement("a");
    open.href = `#run=${encodeURIComponent(run.run_id)}`;
    open.textContent = run.run_id;
    const meta = document.createElement("span");
    meta.className = "meta";
    meta.textContent = `${run.procedure} · ${new Date(run.started).toLocaleString()}` +
      (run.live ? ` · live, ${run.status}, ${run.mode}` : "");
    const report = document.createElement("a");
    report.href = `/runs/${encodeURIComponent(run.run_id)}/report`;
    report.textContent = "report";
    report.className = "report-link";
    report.target = "_blank";
    item.append(open, meta, report);
    if (run.live) item.classList.add("live");
    return item;
  }));
}

$("refresh-runs").addEventListener("click", loadRuns);

$("start-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  $("start-error").textContent = "";
  const form = new FormData($("start-form"));
  $("start-button").disabled = true;
  try {
    const {run_id} = await api("POST", "/api/runs", {
      procedure: form.get("procedure"), binding: form.get("binding"), mode: form.get("mode"),
    });
    location.hash = `run=${encodeURIComponent(run_id)}`;
    await loadRuns();
  } catch (error) {
    $("start-error").textContent = error.message;
  } finally {
    $("start-button").disabled = false;
  }
});

window.addEventListener("hashchange", openRunFromHash);

function openRunFromHash() {
  const match = /run=([^&]+)/.exec(location.hash);
  if (match && view.me) openRun(decodeURIComponent(match[1]));
}

async function openRun(runId) {
  closeSocket();
  view.runId = runId;
  view.events = [];
  view.telemetry.clear();
  view.lastImageSeq = null;
  $("action-error").textContent = "";
  let data;
  try {
    data = await api("GET", `/api/runs/${encodeURIComponent(runId)}`);
  } catch (error) {
    $("action-error").textContent = error.message;
    return;
  }
  view.procedure = data.procedure;
  buildProcedure();
  $("no-run").hidden = true;
  $("run-view").hidden = false;
  $("audit").tBodies[0].replaceChildren();
  applyUpdate(data);
  if (data.state.live) connect();
  else setConnection("closed", "past run (from the audit log)");
}

// ---- live connection -------------------------------------------------------------------------
function setConnection(state, text) {
  const badge = $("connection");
  badge.dataset.state = state;
  badge.textContent = text;
}

function connect() {
  const runId = view.runId;
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  setConnection("connecting", "connecting…");
  const socket = new WebSocket(`${scheme}://${location.host}/ws/runs/${encodeURIComponent(runId)}`);
  view.socket = socket;
  socket.addEventListener("open", () => setConnection("open", "live"));
  socket.addEventListener("message", (message) => {
    const data = JSON.parse(message.data);
    if (data.type === "update" && view.runId === runId) applyUpdate(data);
  });
  socket.addEventListener("close", (event) => {
    if (view.socket !== socket) return;  // replaced on purpose
    view.socket = null;
    if (event.code === 1008) {
      setConnection("closed", `closed: ${event.reason || "refused"}`);
      return;
    }
    setConnection("reconnecting", "connection lost; reconnecting…");
    view.reconnectTimer = setTimeout(() => { if (view.runId === runId) openRun(runId); }, 2000);
  });
}

function closeSocket() {
  clearTimeout(view.reconnectTimer);
  const socket = view.socket;
  view.socket = null;
  if (socket) socket.close();
  setConnection("idle", "not connected");
}

// ---- applying updates ------------------------------------------------------------------------
function applyUpdate(data) {
  view.state = data.state;
  const seen = new Set(view.events.map((e) => e.seq));
  const fresh = (data.events || []).filter((e) => !seen.has(e.seq));
  view.events.push(...fresh);
  for (const reading of data.telemetry || []) {
    view.telemetry.set(`${reading.system}.${reading.item}`, {...reading, receivedAt: performance.now()});
  }
  appendAudit(fresh);
  renderRun();
}

function appendAudit(events) {
  const body = $("audit").tBodies[0];
  for (const event of events) {
    const row = body.insertRow(0);
    row.dataset.kind = event.kind;
    row.dataset.actor = event.actor;
    row.dataset.instruction = event.instruction || "";
    const cells = [event.seq, new Date(event.time).toLocaleTimeString(), event.actor, event.kind.replaceAll("_", " "),
      event.instruction || "", summarize(event)];
    for (const text of cells) row.insertCell().textContent = text;
  }
}

function summarize(event) {
  const data = event.data || {};
  switch (event.kind) {
    case "command_sent": return `${data.system}.${data.command} ${JSON.stringify(data.args)}`;
    case "command_result": return `${data.success ? "success" : "FAILED"}${data.message ? ": " + data.message : ""}` +
      (data.values && Object.keys(data.values).length ? ` ${JSON.stringify(data.values)}` : "");
    case "operator_input": return `${data.name} = ${JSON.stringify(data.value)}`;
    case "telemetry_seen": return `${data.system}.${data.item} = ${JSON.stringify(data.value)}${data.stale ? " (stale)" : ""}`;
    case "run_started": return `${data.procedure} (${data.mode})`;
    case "mode_changed": return data.mode;
    default: return data.reason || "";
  }
}

// ---- drawing the procedure -------------------------------------------------------------------
const KIND_LABEL = {command: "Send", verify: "Check", wait: "Start wait", if: "Evaluate", goto: "Go", call: "Run"};

function buildProcedure() {
  const list = $("procedure");
  list.replaceChildren();
  const procedure = view.procedure;
  $("proc-title").textContent = procedure ? `${procedure.title} (v${procedure.version})` : "procedure file not available";
  if (!procedure) return;
  for (const step of procedure.steps) {
    const item = document.createElement("li");
    item.className = "step";
    const title = document.createElement("h3");
    title.textContent = `${step.number}. ${step.title}`;
    item.append(title, ...step.notices.map(noticeBox));
    const instructions = document.createElement("ol");
    instructions.className = "instructions";
    for (const instruction of step.instructions) instructions.append(buildInstruction(instruction));
    item.append(instructions);
    list.append(item);
  }
}

function noticeBox(notice) {
  const box = document.createElement("div");
  box.className = `notice ${notice.level}`;
  const label = document.createElement("strong");
  label.textContent = notice.level.toUpperCase();
  box.append(label, " ", notice.text);
  return box;
}

function element(tag, className, text) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined) node.textContent = text;
  return node;
}

function buildInstruction(instruction, prefix = "") {
  const number = prefix + instruction.number;  // as the executive numbers it, e.g. 2.1/1.3
  const item = element("li", `instruction kind-${instruction.kind}`);
  item.dataset.number = number;
  item.append(...instruction.notices.map(noticeBox));
  const line = element("div", "line");
  const breakpoint = element("button", "breakpoint", number);
  breakpoint.type = "button";
  breakpoint.title = "toggle a breakpoint here";
  breakpoint.addEventListener("click", () => {
    const set = view.state && view.state.breakpoints.includes(number);
    act(set ? "clear_breakpoint" : "set_breakpoint", {instruction: number});
  });
  line.append(breakpoint);
  const paxCan = instruction.automatable && !instruction.needs_operator;
  const icon = element("span", paxCan ? "auto-icon" : "auto-icon operator", paxCan ? "⚙" : "OP");
  icon.title = paxCan ? "automatable: PAX can run this" : "an operator must perform this";
  if (paxCan) item.classList.add("automatable");
  line.append(icon, element("span", "text", instruction.text));
  if (instruction.hazardous) {
    const hazard = element("span", "hazard", "⚠ hazardous");
    hazard.title = "needs confirmation before it is sent, even in autonomous mode";
    line.append(hazard);
  }
  if (instruction.telemetry) {
    const chip = element("span", "telemetry");
    chip.dataset.key = `${instruction.telemetry.system}.${instruction.telemetry.item}`;
    line.append(chip);
  }
  item.append(line);
  const controls = element("div", "instruction-controls");
  if (instruction.kind === "record") controls.append(...recordInput(instruction, number));
  else if (instruction.kind === "manual") controls.append(button("Done", "done", () => act("done", {instruction: number})));
  else controls.append(button(KIND_LABEL[instruction.kind] || "Perform", "perform", () => perform(instruction, number)));
  controls.append(
    button("Confirm", "confirm", () => confirmHazard(instruction, number, false)),
    button("Retry", "retry", () => act("retry", {instruction: number})),
    button("Skip…", "skip", () => skip(number)),
  );
  item.append(controls, element("div", "mark"), element("div", "detail"));
  if (instruction.callee) item.append(buildCallee(instruction.callee, `${number}/`));
  return item;
}

// A called sub-procedure, drawn inside its call with the executive's numbers (call/number).
function buildCallee(callee, prefix) {
  const box = element("ol", "callee");
  for (const step of callee.steps) {
    const heading = element("li", "callee-step", `${prefix}${step.number}. ${step.title} (${callee.title})`);
    box.append(heading, ...step.notices.map(noticeBox));
    for (const instruction of step.instructions) box.append(buildInstruction(instruction, prefix));
  }
  return box;
}

function button(text, className, onClick) {
  const node = element("button", className, text);
  node.type = "button";
  node.addEventListener("click", onClick);
  return node;
}

function recordInput(instruction, number) {
  const record = instruction.record;
  let input;
  if (record.choices) {
    input = document.createElement("select");
    input.append(...record.choices.map((choice) => new Option(choice, choice)));
  } else if (record.type === "boolean") {
    input = document.createElement("select");
    input.append(new Option("true", "true"), new Option("false", "false"));
  } else {
    input = document.createElement("input");
    if (record.type === "integer" || record.type === "real") {
      input.type = "number";
      input.step = record.type === "integer" ? "1" : "any";
      if (record.min !== null) input.min = record.min;
      if (record.max !== null) input.max = record.max;
    } else {
      input.type = "text";
      if (record.pattern) input.pattern = record.pattern;
    }
    input.required = true;
  }
  input.className = "record-value";
  input.name = record.name;
  input.setAttribute("aria-label", `${record.name} (${record.type})`);
  const submit = button("Record", "record", () => {
    if (input.reportValidity && !input.reportValidity()) return;
    act("enter", {instruction: number, value: typedValue(record.type, input.value)});
  });
  return [element("span", "record-name", `${record.name} (${record.type})`), input, submit];
}

function typedValue(type, text) {
  if (type === "integer" && /^-?\d+$/.test(text)) return Number(text);
  if (type === "real" && text.trim() !== "" && !Number.isNaN(Number(text))) return Number(text);
  if (type === "boolean") return text === "true";
  return text;  // the server converts and validates, and says what is wrong
}

async function perform(instruction, number) {
  if (instruction.hazardous && view.state.hold !== "failure") {
    confirmHazard(instruction, number, true);
    return;
  }
  await act("perform", {instruction: number});
}

function confirmHazard(instruction, number, thenSend) {
  const dialog = $("confirm-dialog");
  $("confirm-text").textContent = `${number}: ${instruction.text}. Confirm that it is safe to send.`;
  dialog.returnValue = "";
  dialog.onclose = async () => {
    if (dialog.returnValue !== "confirm") return;
    await act("confirm", {instruction: number});
    if (thenSend && view.state.mode === "manual") await act("perform", {instruction: number});
  };
  dialog.showModal();
}

function skip(number) {
  const dialog = $("skip-dialog");
  $("skip-number").textContent = number;
  $("skip-reason").value = "";
  dialog.returnValue = "";
  dialog.onclose = () => {
    const reason = $("skip-reason").value.trim();
    if (dialog.returnValue === "skip" && reason) act("skip", {instruction: number, reason});
  };
  dialog.showModal();
}

// ---- rendering state -------------------------------------------------------------------------
function renderRun() {
  const state = view.state;
  if (!state) return;
  $("run-id").textContent = state.run_id;
  $("run-status").textContent = state.status;
  $("run-status").dataset.status = state.status;
  $("run-mode").textContent = state.mode || "";
  $("hold").textContent = state.error ? `Recording failed: ${state.error}` : (state.reason || "");
  const live = Boolean(state.live) && state.status === "active";
  const mayAct = Boolean(view.me && view.me.may_act) && live;
  for (const id of ["mode-manual", "mode-autonomous"]) {
    const node = $(id);
    node.setAttribute("aria-pressed", String(node.dataset.mode === state.mode));
    node.disabled = !mayAct || node.dataset.mode === state.mode;
  }
  // pausing in manual mode keeps automation held when someone switches to autonomous
  $("pause").disabled = !mayAct || state.paused;
  $("continue").disabled = !mayAct || !(state.paused || state.hold === "breakpoint");
  $("step").disabled = !mayAct || state.executing || !state.current;
  $("stop").disabled = !mayAct;
  $("controls").hidden = !state.live;
  for (const item of document.querySelectorAll("#procedure li.instruction")) renderInstruction(item, state, mayAct);
  renderTelemetry();
  renderCamera();
  renderTrajectory();
}

function renderInstruction(item, state, mayAct) {
  const number = item.dataset.number;
  const running = Boolean(state.live) && state.status === "active";  // controls only on a running run
  const status = (state.statuses && state.statuses[number]) ||
    (state.instructions[number] && state.instructions[number].status) || "pending";
  const details = state.instructions[number] || {};
  const current = state.current === number;
  item.dataset.status = status;
  item.classList.toggle("current", current);
  item.classList.toggle("has-breakpoint", state.breakpoints.includes(number));
  const idle = mayAct && current && !state.executing;
  const failed = state.hold === "failure" || state.hold === "in_flight";
  const held = state.mode === "manual" || ["not_automatable", "confirmation", "breakpoint", "paused"].includes(state.hold);
  const kind = [...item.classList].find((c) => c.startsWith("kind-")).slice(5);
  const own = (selector) => item.querySelector(`:scope > ${selector}`);  // not those of a called sub-procedure
  own(".line > .breakpoint").disabled = !mayAct;
  const show = (selector, visible, enabled) => {
    const node = own(`.instruction-controls > ${selector}`);
    if (!node) return;
    node.hidden = !visible;
    node.disabled = !enabled;
  };
  // Send and its kin: on every such instruction in manual mode, on the held one in autonomous mode
  show(".perform", running && (state.mode === "manual" || current), idle && held && !failed);
  show(".confirm", running && current && state.hold === "confirmation", idle);
  show(".done", running, idle && kind === "manual");
  show(".record", running, idle);
  const input = own(".instruction-controls > .record-value");
  if (input) input.disabled = !idle;
  show(".retry", running && current && failed, idle);
  show(".skip", running && current, idle);
  const mark = own(".mark");
  const who = details.actor ? ` by ${details.actor}` : "";
  const when = details.time ? ` at ${new Date(details.time).toLocaleTimeString()}` : "";
  const reason = details.reason ? ` — ${details.reason}` : "";
  mark.textContent = {
    completed: `✓ completed${who}${when}`, failed: `✗ failed${who}${when}${reason}`,
    skipped: `⤼ skipped${who}${when}${reason}`, executing: `… in progress${who}`,
    active: current && state.reason ? `▶ ${state.reason}` : "",
  }[status] || "";
  const detail = own(".detail");
  const parts = [];
  if (details.sent) parts.push(`sent ${details.sent.system}.${details.sent.command}(${formatArgs(details.sent.args)})`);
  if (details.result) {
    const values = details.result.values && Object.keys(details.result.values).length ? ` ${JSON.stringify(details.result.values)}` : "";
    parts.push(`result: ${details.result.success ? "success" : "FAILED"}${details.result.message ? " — " + details.result.message : ""}${values}`);
  }
  if (details.value !== undefined) parts.push(`recorded ${JSON.stringify(details.value)}`);
  if (details.telemetry) parts.push(`saw ${details.telemetry.system}.${details.telemetry.item} = ${JSON.stringify(details.telemetry.value)}${details.telemetry.stale ? " (stale)" : ""}`);
  detail.textContent = parts.join(" · ");
}

function formatArgs(args) {
  return Object.entries(args || {}).map(([name, value]) => `${name}=${JSON.stringify(value)}`).join(", ");
}

function renderTelemetry() {
  const now = performance.now();
  for (const chip of document.querySelectorAll("#procedure .telemetry")) {
    const reading = view.telemetry.get(chip.dataset.key);
    if (!reading) {
      chip.textContent = view.state && view.state.live ? `${chip.dataset.key}: no value` : "";
      chip.dataset.stale = "true";
      continue;
    }
    const age = reading.age === null || reading.age === undefined ? null : reading.age + (now - reading.receivedAt) / 1000;
    const value = reading.error ? reading.error : JSON.stringify(reading.value);
    chip.textContent = `${chip.dataset.key} = ${value}` + (age === null ? "" : ` · ${age.toFixed(1)} s ago`) +
      (reading.stale ? " · STALE" : "");
    chip.dataset.stale = String(Boolean(reading.stale));
  }
}

setInterval(renderTelemetry, 500);

function renderCamera() {
  const camera = view.state.camera;
  if (!camera || camera.version === view.lastImageSeq) return;
  view.lastImageSeq = camera.version;
  const image = $("camera");
  image.src = `/api/runs/${encodeURIComponent(view.runId)}/camera?v=${encodeURIComponent(camera.version)}`;
  image.hidden = false;
  $("camera-caption").textContent = camera.caption;
}

// The end pose of the last planned trajectory, drawn top-down (x right, y up) with its height.
function renderTrajectory() {
  const box = $("trajectory");
  const plans = view.events.filter((e) => e.kind === "command_result" && e.data.values && e.data.values.end_pose);
  const planTelemetry = [...view.telemetry.values()].filter((r) => r.item === "plan_valid" || r.item === "plan_status");
  const lines = planTelemetry.map((r) => `${r.system}.${r.item} = ${JSON.stringify(r.value)}${r.stale ? " (stale)" : ""}`);
  if (!plans.length) {
    box.textContent = (lines.length ? lines.join(" · ") + ". " : "") +
      "No end pose yet: it is drawn when a plan result carries one (values.end_pose).";
    return;
  }
  const latest = plans[plans.length - 1];
  const pose = normalizePose(latest.data.values.end_pose);
  if (!pose) {
    box.textContent = `end pose not understood: ${JSON.stringify(latest.data.values.end_pose)}`;
    return;
  }
  const scale = 60, cx = 100, cy = 100;
  const x = cx + pose.x * scale, y = cy - pose.y * scale;
  const dx = Math.cos(pose.yaw) * 20, dy = -Math.sin(pose.yaw) * 20;
  box.innerHTML = `<svg viewBox="0 0 200 200" class="pose" role="img" aria-label="planned end pose">
    <line x1="0" y1="${cy}" x2="200" y2="${cy}" class="axis"/><line x1="${cx}" y1="0" x2="${cx}" y2="200" class="axis"/>
    <circle cx="${cx}" cy="${cy}" r="4" class="base"/>
    <line x1="${x}" y1="${y}" x2="${x + dx}" y2="${y + dy}" class="heading"/>
    <circle cx="${x}" cy="${y}" r="6" class="end"/></svg>`;
  const caption = element("p", "pose-text",
    `${latest.instruction}: end pose x=${pose.x.toFixed(3)} y=${pose.y.toFixed(3)} z=${pose.z.toFixed(3)} m, ` +
    `yaw=${(pose.yaw * 180 / Math.PI).toFixed(1)}° (top view, robot base at the centre, ±${(100 / scale).toFixed(2)} m shown)` +
    (lines.length ? ` · ${lines.join(" · ")}` : ""));
  box.append(caption);
}

function normalizePose(pose) {
  if (Array.isArray(pose) && pose.length >= 3) return {x: +pose[0], y: +pose[1], z: +pose[2], yaw: +(pose[5] || 0)};
  if (pose && typeof pose === "object" && "x" in pose) return {x: +pose.x, y: +pose.y, z: +(pose.z || 0), yaw: +(pose.yaw || 0)};
  return null;
}

// ---- run controls ----------------------------------------------------------------------------
for (const id of ["mode-manual", "mode-autonomous"]) {
  $(id).addEventListener("click", () => act("mode", {mode: $(id).dataset.mode}));
}
$("pause").addEventListener("click", () => act("pause"));
$("continue").addEventListener("click", () => act("continue"));
$("step").addEventListener("click", () => act("step"));
$("stop").addEventListener("click", () => {
  if (confirm("Stop this run? It can be resumed later from the audit log.")) act("stop", {reason: "stopped from the web view"});
});

loadSession();
