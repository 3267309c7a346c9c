// Caretaker operator view: sign-in, the runs list, the live connection and the run controls
// (run_view.js draws the run). Plain JS, no build step, nothing loaded from elsewhere.
//
// The server is the authority: this page draws what /api/runs/ID and the run's WebSocket say
// and sends every action to /api/runs/ID/actions, where the executive accepts or refuses it
// (observers are refused there too; disabled buttons are only a courtesy). Every request that
// changes something carries the session's CSRF token.
"use strict";

const $ = (id) => document.getElementById(id);

function element(tag, className, text) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined) node.textContent = text;
  return node;
}
const RECONNECT_MS = 2000;

const view = {
  me: null,            // {user, name, role, may_act, csrf}
  runId: null,
  procedure: null,     // procedure JSON (steps, instructions as sentences)
  state: null,         // run state JSON (executive snapshot + per-instruction details)
  events: [],          // audit events seen so far
  telemetry: new Map(),// "system.item" -> {value, age, stale, out, receivedAt}
  checks: {},          // check key -> whether the instruction's test of that telemetry holds now
  clockOffset: 0,      // server clock minus this browser's, in ms (countdowns use the server's times)
  socket: null,
  opening: 0,          // counts openRun calls: an answer to one that a later call overtook is dropped
  drawn: "",           // the run and procedure drawn: opened again (a reconnect), they are not drawn anew
  reconnectTimer: null,
  lastLoss: "",        // when and why the run's connection was last lost
  lastImageSeq: null,
  followed: null,      // the instruction last scrolled to
  envsSeen: "",
  runsSocket: null,    // pushes the runs list whenever it changes (on any console)
  runsPushes: 0,       // lists pushed so far: a GET answer overtaken by a push is not shown
  runsTimer: null,     // reconnects it
};

// ---- server calls ----------------------------------------------------------------------------
async function api(method, path, body) {
  const headers = body === undefined ? {} : {"Content-Type": "application/json"};
  if (method !== "GET" && view.me) headers["X-CSRF-Token"] = view.me.csrf;
  const response = await fetch(path, {method, headers, body: body === undefined ? undefined : JSON.stringify(body)});
  const data = await response.json().catch(() => ({}));
  if (!response.ok) {
    const error = new Error(data.error || `${response.status} ${response.statusText}`);
    error.status = response.status;
    error.data = data;
    if (response.status === 401 && view.me && path !== "/api/session") signedOut(error.message);
    throw error;
  }
  return data;
}

// A refused action says why under the run's controls; a refused record, next to its field.
async function act(action, extra = {}) {
  $("action-error").textContent = "";
  const field = action === "enter" ? recordError(extra.instruction) : null;
  if (field) field.textContent = "";
  try {
    const runId = view.runId;
    const answer = await api("POST", `/api/runs/${encodeURIComponent(runId)}/actions`, {action, ...extra});
    const known = answer.result;  // an action to a far run: on its way (action_news.js follows it)
    if (known && typeof known === "object" && known.request !== undefined) followAction(runId, known);
  } catch (error) {
    (field || $("action-error")).textContent = error.message;
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
  closeRunsSocket();
  if (view.me) {
    $("start-panel").hidden = !view.me.may_act;
    await Promise.all([loadCatalog(), loadRuns()]);
    connectRuns();
    loadProposals();  // proposals.js
    openRunFromHash();
  }
}

function signedOut(message) {
  view.me = null;
  closeSocket();
  closeRunsSocket();
  $("main-view").hidden = true;
  $("sign-out").hidden = true;
  $("who").textContent = "";
  $("sign-in-view").hidden = false;
  $("sign-in-error").textContent = message || "";
}

$("sign-in-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  $("sign-in-error").textContent = "";
  try {
    view.me = await api("POST", "/api/session", {user: $("user-id").value.trim(), password: $("password").value});
    $("password").value = "";
    await loadSession();
  } catch (error) {
    $("sign-in-error").textContent = error.message;
  }
});

$("sign-out").addEventListener("click", async () => {
  await api("DELETE", "/api/session").catch(() => {});
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
  fillSelect($("resume-binding"), catalog.bindings);
}

const STATUS_WORDS = {active: "running", completed: "completed", stopped: "stopped", interrupted: "interrupted (no end recorded)"};

function hostWords(run) {
  if (run.host_lost) return ` · ${run.host_lost.host} went silent at ${new Date(run.host_lost.since).toLocaleTimeString()}`;
  if (!run.host) return "";
  return run.hosted_here ? " · on this console" : ` · on ${run.host}`;
}

// An answer to a GET that a push overtook is older than what the page shows: the push wins (the
// server pushes again whenever the list changes after what it pushed).
async function loadRuns() {
  const pushes = view.runsPushes;
  const {runs} = await api("GET", "/api/runs");
  if (view.runsPushes === pushes) showRuns(runs);
}

// the runs list, pushed by the server whenever it changes on any console
function connectRuns() {
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const socket = new WebSocket(`${scheme}://${location.host}/ws/runs`);
  view.runsSocket = socket;
  socket.addEventListener("message", (message) => {
    const data = JSON.parse(message.data);
    if (data.type === "runs") {
      view.runsPushes += 1;
      showRuns(data.runs);
    } else if (data.type === "fleet") {
      showFleet(data.robots);  // fleet.js
    }
  });
  socket.addEventListener("close", (event) => {
    if (view.runsSocket !== socket) return;  // replaced on purpose
    view.runsSocket = null;
    if (event.code === 1008) {
      if (view.me && /sign in|session/.test(event.reason)) signedOut(event.reason);
      return;
    }
    view.runsTimer = setTimeout(() => { if (view.me) { loadRuns().catch(() => {}); connectRuns(); } }, RECONNECT_MS);
  });
}

function closeRunsSocket() {
  clearTimeout(view.runsTimer);
  const socket = view.runsSocket;
  view.runsSocket = null;
  if (socket) socket.close();
}

function showRuns(runs) {
  $("run-list").replaceChildren(...runs.map((run) => {
    const item = element("li");
    item.dataset.runId = run.run_id;
    item.dataset.status = run.status;
    item.dataset.host = run.host || "";
    item.classList.toggle("live", Boolean(run.live));
    item.classList.toggle("open", run.run_id === view.runId);
    const open = element("a", "", run.run_id);
    open.href = `#run=${encodeURIComponent(run.run_id)}`;
    const status = element("span", "run-status", STATUS_WORDS[run.status] || run.status);
    const line = element("span", "run-line");
    line.append(status);
    if (run.rehearsal) {  // marked as in the run's header: a draft or changed file, run on a simulator
      const badge = element("span", "badge version", "REHEARSAL");
      badge.dataset.rehearsal = "true";
      line.append(" ", badge);
    }
    const meta = element("span", "meta", `${run.procedure} · ${new Date(run.started).toLocaleString()}` +
      (run.live ? ` · ${run.mode}, started by ${run.started_by}` : "") + hostWords(run));
    const report = element("a", "report-link", "report");
    report.href = `/runs/${encodeURIComponent(run.run_id)}/report`;
    report.target = "_blank";
    item.append(open, line, meta, report);
    if (run.unsupervised && view.me && view.me.may_act) item.append(attachButton(run));  // attach.js
    if (run.approval) {
      // every console lists it: a second operator need not have the run open to see it waits for them
      const wanted = element("span", "approval-wanted",
        `⚠ ${run.approval.number}: ${run.approval.command} — sent by ${run.approval.sender}, waits for a second operator's approval`);
      item.append(wanted);
    }
    return item;
  }));
}

$("refresh-runs").addEventListener("click", () => loadRuns().catch(() => {}));

// A start refused because another run controls the robot offers a takeover (with a reason, logged in both runs);
// an onboard start whose commands need approval asks for a second operator's, signed here with their password.
async function startRun(takeOver, approval = {}) {
  $("start-error").textContent = "";
  $("take-over").hidden = true;
  const form = new FormData($("start-form"));
  $("start-button").disabled = true;
  try {
    const {run_id} = await api("POST", "/api/runs", {
      procedure: form.get("procedure"), binding: form.get("binding"), mode: form.get("mode"), take_over: takeOver,
      onboard: form.get("onboard") === "on", rehearsal: form.get("rehearsal") === "on", ...approval,
    });
    $("uplink-approval").hidden = true;
    location.hash = `run=${encodeURIComponent(run_id)}`;
    await loadRuns();
  } catch (error) {
    $("start-error").textContent = error.message;
    const needed = error.data && error.data.approvals_needed;
    if (needed) {
      $("uplink-approval-list").replaceChildren(...needed.map((text) => element("li", "", text)));
      $("uplink-approval").hidden = false;
    }
    const holder = error.data && error.data.controlled_by;
    if (holder) {
      $("take-over").hidden = false;
      $("take-over").textContent = `Take over ${holder.robot} from ${holder.user}…`;
      $("take-over").dataset.from = `run ${holder.run_id} of ${holder.user}, in control since ${new Date(holder.since).toLocaleTimeString()}`;
    }
  } finally {
    $("start-button").disabled = false;
  }
}

$("start-form").addEventListener("submit", (event) => {
  event.preventDefault();
  $("uplink-approval").hidden = true;
  startRun(null);
});
$("approve-uplink").addEventListener("click", async () => {
  const password = $("approver-password");
  await startRun(null, {approver: $("approver-user").value.trim(), approver_password: password.value});
  password.value = "";
});
$("take-over").addEventListener("click", async () => {
  const answer = await askReason("Take over the robot", `${$("take-over").dataset.from} holds and sends nothing more.`, "Take over");
  if (answer) await startRun(answer.reason);
});

// A dialog asking why (and, with `value`, a new value): resolves to {reason, value}, or null when cancelled.
function askReason(title, text, okLabel, value) {
  const dialog = $("reason-dialog");
  $("reason-title").textContent = title;
  $("reason-text").textContent = text;
  $("reason-yes").textContent = okLabel;
  $("reason-input").value = "";
  $("reason-value-label").hidden = value === undefined;
  $("reason-value").required = value !== undefined;
  $("reason-value").value = value === undefined ? "" : value;
  dialog.returnValue = "";
  return new Promise((resolve) => {
    dialog.onclose = () => {
      const reason = $("reason-input").value.trim();
      resolve(dialog.returnValue === "ok" && reason ? {reason, value: $("reason-value").value} : null);
    };
    dialog.showModal();
  });
}

window.addEventListener("hashchange", openRunFromHash);

function openRunFromHash() {
  const match = /run=([^&]+)/.exec(location.hash);
  if (match && view.me) openRun(decodeURIComponent(match[1]));
}

// Opening is asynchronous and may be asked again before it finished (a hash change while signing
// in, a reconnect): only the last call draws, or the audit list would be redrawn from one answer
// with only the events the other had not shown.
async function openRun(runId) {
  const opening = ++view.opening;
  closeSocket();
  const again = view.runId === runId;
  view.runId = runId;
  view.events = [];
  view.telemetry.clear();
  view.checks = {};
  view.lastImageSeq = null;
  if (!again) view.followed = null;  // a reconnect does not scroll the page under the operator's pointer
  view.envsSeen = "";
  $("action-error").textContent = "";
  if (!again) clearActionNews();
  let data;
  try {
    data = await api("GET", `/api/runs/${encodeURIComponent(runId)}`);
  } catch (error) {
    if (opening !== view.opening) return;
    $("action-error").textContent = error.message;
    if (error.status === undefined || error.status >= 500) reopenLater(runId, error.message);  // the network or the server, not a refusal
    return;
  }
  if (opening !== view.opening) return;  // opened again meanwhile (this run or another): that call draws
  view.procedure = data.procedure;
  // Drawn anew only when it changed: a reconnect must not replace the buttons and fields under
  // the operator's pointer (a click would land on a detached node; a typed entry would be lost).
  const drawn = JSON.stringify([runId, data.procedure]);
  if (drawn !== view.drawn) buildProcedure();
  view.drawn = drawn;
  $("no-run").hidden = true;
  $("run-view").hidden = false;
  $("audit").replaceChildren();
  for (const item of document.querySelectorAll("#run-list li")) item.classList.toggle("open", item.dataset.runId === runId);
  applyUpdate(data);
  spatialPanel.open(runId, Boolean(data.state.live));  // the 3D view (spatial_panel.js)
  if (data.state.live) connect();
  else setConnection("closed", "past run (from the audit log)");
}

// ---- live connection -------------------------------------------------------------------------
function setConnection(state, text) {
  const badge = $("connection");
  badge.dataset.state = state;
  badge.textContent = text;
  badge.title = view.lastLoss || "";
}

function connect() {
  const runId = view.runId;
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  setConnection("connecting", "connecting…");
  const socket = new WebSocket(`${scheme}://${location.host}/ws/runs/${encodeURIComponent(runId)}`);
  view.socket = socket;
  socket.addEventListener("open", () => setConnection("open", "live"));
  socket.addEventListener("message", (message) => {
    if (view.socket !== socket) return;  // closed on purpose: a new opening draws from its own answer
    const data = JSON.parse(message.data);
    if (data.type === "update") applyUpdate(data);
  });
  socket.addEventListener("close", (event) => {
    if (view.socket !== socket) return;  // replaced on purpose
    view.socket = null;
    if (event.code === 1000 && event.reason === "the run ended") {
      if (view.runId === runId) openRun(runId);  // now a past run: drawn from the audit log, resumable when stopped
      return;
    }
    if (event.code === 1008) {
      setConnection("closed", `closed: ${event.reason || "refused"}`);
      if (view.me && /sign in|session/.test(event.reason)) signedOut(event.reason);  // the first to learn it says why
      return;
    }
    reopenLater(runId, `closed with code ${event.code}${event.reason ? ` (${event.reason})` : ""}`);
  });
}

// The badge's tooltip keeps when and why the connection was last lost, once it is live again.
function reopenLater(runId, why) {
  view.lastLoss = `lost at ${new Date().toLocaleTimeString()}: ${why}`;
  setConnection("reconnecting", "connection lost; reconnecting…");
  view.reconnectTimer = setTimeout(() => { if (view.runId === runId) openRun(runId); }, RECONNECT_MS);
}

function closeSocket() {
  clearTimeout(view.reconnectTimer);
  const socket = view.socket;
  view.socket = null;
  if (socket) socket.close();
  setConnection("idle", "not connected");
}

// ---- the server's clock -----------------------------------------------------------------------
// Each update says the server's time when it left; it arrives later by however long it took, so
// each sample puts the server's clock behind by that delay (under load 0.1-0.3 s: an arm's age
// then read less than the light time). The least delayed sample of the last CLOCK_WINDOW_MS is
// the best estimate: the largest offset.
const CLOCK_WINDOW_MS = 30000;
const clockSamples = [];  // [received at (this browser's ms), server minus browser (ms)]

function noteServerTime(serverTime) {
  const now = Date.now();
  clockSamples.push([now, serverTime * 1000 - now]);
  while (clockSamples.length > 1 && now - clockSamples[0][0] > CLOCK_WINDOW_MS) clockSamples.shift();
  view.clockOffset = Math.max(...clockSamples.map(([, offset]) => offset));
}

// ---- applying updates ------------------------------------------------------------------------
function applyUpdate(data) {
  const was = view.state;
  const before = was ? was.status : null;
  view.state = data.state;
  // a refusal says why an act could not be done there and then: once the run moved on, it is past
  if (was && ["current", "hold", "status"].some((key) => was[key] !== data.state[key])) {
    for (const refusal of document.querySelectorAll("#action-error, #procedure .record-error")) refusal.textContent = "";
  }
  if (data.server_time) noteServerTime(data.server_time);
  const seen = new Set(view.events.map((e) => e.seq));
  const fresh = (data.events || []).filter((e) => !seen.has(e.seq));
  view.events.push(...fresh);
  const telemetry = data.telemetry || {readings: [], checks: {}};
  for (const reading of telemetry.readings || []) {
    view.telemetry.set(`${reading.system}.${reading.item}`, {...reading, receivedAt: performance.now()});
  }
  view.checks = telemetry.checks || {};
  appendAudit(fresh);
  renderRun();
  if (before !== null && before !== data.state.status) loadRuns().catch(() => {});
}

// ---- run controls ----------------------------------------------------------------------------
for (const id of ["mode-manual", "mode-autonomous"]) {
  $(id).addEventListener("click", () => act("mode", {mode: $(id).dataset.mode}));
}
$("pause").addEventListener("click", () => act("pause"));
$("continue").addEventListener("click", () => act("continue"));
$("hold-continue").addEventListener("click", () => act("continue"));  // the banner's way on after a halt
$("step").addEventListener("click", () => act("step"));
// HALT acts at once: no dialog between the operator and the arm stopping (the reason is optional).
// It acts on the press, as an emergency stop does, not on the release a person makes a tenth of a
// second later; Enter or Space (a click with no pointer: detail 0) acts through click. The button
// says "halting…" from then until the console has answered, so the operator sees the press was
// taken before the banner can change (that waits for the habitat).
async function halt() {
  const button = $("halt");
  const reason = $("halt-reason").value.trim();
  $("halt-reason").value = "";
  window.caretakerSpatial?.yieldFrames(2); // the next frame shows "halting…" without waiting for the 3D view
  button.dataset.state = "halting";
  button.textContent = "halting…";
  try {
    await act("halt", {reason});
  } finally {
    delete button.dataset.state;
    button.textContent = "HALT";
  }
}
$("halt").addEventListener("pointerdown", (event) => {
  if (event.button === 0 && !$("halt").disabled) halt();
});
$("halt").addEventListener("click", (event) => {
  if (event.detail === 0) halt();  // a pointer's click follows the press that already halted
});
$("ask-again").addEventListener("click", () => act("ask_again", {instruction: view.state.current}));
// after a halted motion: back to the instruction that planned it, which plans again from where the arm is
$("replan").addEventListener("click", () => act("replan", {instruction: view.state.current}));
for (const outcome of ["succeeded", "failed"]) {
  $(`resolve-${outcome}`).addEventListener("click", async () => {
    const number = view.state.current;
    const answer = await askReason(`Record that ${number} ${outcome}`,
      "Record what the system shows (camera, telemetry, a crew report). The log keeps it with your name.", `Record: ${outcome}`);
    if (answer) await act("resolve", {instruction: number, value: outcome, reason: `${answer.reason}`});
  });
}
$("take-control").addEventListener("click", async () => {
  const answer = await askReason("Take control back", `${view.state.reason}. The other run then holds.`, "Take control");
  if (answer) await act("take_control", {reason: answer.reason});
});
$("stop").addEventListener("click", () => {
  const dialog = $("stop-dialog");
  $("stop-reason").value = "";
  dialog.returnValue = "";
  dialog.onclose = () => {
    const reason = $("stop-reason").value.trim();
    if (dialog.returnValue === "stop" && reason) act("stop", {reason});
  };
  dialog.showModal();
});
$("resume").addEventListener("click", () => {
  const dialog = $("resume-dialog");
  const runId = view.runId;
  $("resume-run").textContent = runId;
  const lost = view.state && view.state.host_lost;
  $("resume-warning").textContent = view.state && view.state.stopped ? "" : lost ?
    `No stop is recorded: ${lost.host}, which ran it, stopped renewing its claim at ${new Date(lost.since).toLocaleTimeString()} ` +
    "(it died or lost the database). Resuming here continues the run from its log." :
    "No stop is recorded and no console hosts it: the runner died, or a terminal (caretaker run) is still running it. " +
    "Resume only if none is.";
  dialog.returnValue = "";
  dialog.onclose = async () => {
    if (dialog.returnValue !== "resume") return;
    const mode = document.querySelector('input[name="resume-mode"]:checked').value;
    try {
      await api("POST", `/api/runs/${encodeURIComponent(runId)}/resume`, {binding: $("resume-binding").value, mode});
      await openRun(runId);
      await loadRuns();
    } catch (error) {
      $("action-error").textContent = error.message;
    }
  };
  dialog.showModal();
});

document.addEventListener("DOMContentLoaded", loadSession);  // after run_view.js has loaded too
