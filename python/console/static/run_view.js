// Caretaker operator view, the run itself: the procedure as sentences, each instruction's state and
// controls, the hold banner, following the current instruction, telemetry against its limits,
// countdowns, camera, planned end pose and the audit log. Loaded after app.js (its `view`, `$`,
// `element`, `act` and `api`) and sentences.js (values and sentences as operators read them);
// monitors.js (limits in words, the Monitors panel) after it. Plain JS, no build step.
"use strict";

function appendAudit(events) {
  const list = $("audit");
  for (const event of events) {
    const item = element("li");
    item.dataset.kind = event.kind;
    item.dataset.actor = event.actor;
    item.dataset.instruction = event.instruction || "";
    if (event.data && event.data.key) item.dataset.key = event.data.key;  // a command's key: the same when asked again
    const head = element("div", "audit-head");
    head.append(element("span", "seq", `#${event.seq}`), element("time", "", new Date(event.time).toLocaleTimeString()),
      element("b", "actor", event.actor), element("span", "kind", event.kind.replaceAll("_", " ")),
      element("span", "at", event.instruction || ""));
    item.append(head, element("div", "audit-detail", event.summary || ""));
    list.prepend(item);
  }
}

// ---- drawing the procedure -------------------------------------------------------------------
const KIND_LABEL = {command: "Send", verify: "Check", wait: "Start wait", if: "Evaluate", goto: "Go", call: "Run"};
const SVG = "http://www.w3.org/2000/svg";

function buildProcedure() {
  const list = $("procedure");
  list.replaceChildren();
  view.sentences = new Map();
  const procedure = view.procedure;
  $("proc-title").textContent = procedure ? `${procedure.title} (v${procedure.version})` : "procedure file not available";
  if (!procedure) return;
  for (const step of procedure.steps) {
    const item = element("li", "step");
    item.append(element("h3", "", `${step.number}. ${step.title}`), ...step.notices.map(noticeBox));
    const instructions = element("ol", "instructions");
    for (const instruction of step.instructions) instructions.append(buildInstruction(instruction));
    item.append(instructions);
    list.append(item);
  }
}

function noticeBox(notice) {
  const box = element("div", `notice ${notice.level}`);
  box.append(element("strong", "", notice.level.toUpperCase()), " ", notice.text);
  return box;
}

// PRIDE's mark for an instruction automation can perform: two circular arrows.
function automatableIcon() {
  const svg = document.createElementNS(SVG, "svg");
  svg.setAttribute("viewBox", "0 0 16 16");
  svg.setAttribute("aria-hidden", "true");
  svg.innerHTML = '<path d="M13.5 6.5A5.6 5.6 0 0 0 3 5" fill="none" stroke="currentColor" stroke-width="1.6"/>' +
    '<path d="M1.8 2.2 3 5.6 6.3 4.4" fill="none" stroke="currentColor" stroke-width="1.6"/>' +
    '<path d="M2.5 9.5A5.6 5.6 0 0 0 13 11" fill="none" stroke="currentColor" stroke-width="1.6"/>' +
    '<path d="M14.2 13.8 13 10.4 9.7 11.6" fill="none" stroke="currentColor" stroke-width="1.6"/>';
  return svg;
}

function buildInstruction(instruction, prefix = "") {
  const number = prefix + instruction.number;  // as the executive numbers it, e.g. 2.1/1.3
  const item = element("li", `instruction kind-${instruction.kind}`);
  item.dataset.number = number;
  if (instruction.timeout !== undefined) item.dataset.timeout = instruction.timeout;
  view.sentences.set(number, instruction.sentence);
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
  const icon = element("span", paxCan ? "auto-icon" : "auto-icon operator");
  icon.title = paxCan ? "automatable: PAX can run this" : "an operator performs this";
  if (paxCan) {
    icon.append(automatableIcon());
    item.classList.add("automatable");
  }
  const text = element("span", "text");
  fillSentence(text, instruction.sentence, {});
  line.append(icon, text);
  if (instruction.hazardous) {
    const hazard = element("span", "hazard", "⚠ hazardous");
    hazard.title = "needs confirmation before it is sent, even in autonomous mode";
    line.append(hazard);
  }
  if (instruction.telemetry) {
    const chip = element("span", "telemetry");
    chip.dataset.key = `${instruction.telemetry.system}.${instruction.telemetry.item}`;
    chip.dataset.check = instruction.telemetry.check;
    chip.dataset.label = instruction.telemetry.label;
    chip.dataset.units = instruction.telemetry.units || "";
    chip.dataset.expected = instruction.telemetry.expected || "";
    chip.title = `${chip.dataset.key}` + (instruction.telemetry.limits ? ` · SysRep limits ${limitsText(instruction.telemetry.limits)}` : "");
    line.append(chip);
  }
  item.append(line, element("div", "raw", instruction.raw));
  const controls = element("div", "instruction-controls");
  if (instruction.kind === "record") controls.append(...recordInput(instruction, number));
  else if (instruction.kind === "manual") controls.append(button("Done", "done", () => act("done", {instruction: number})));
  else controls.append(button(KIND_LABEL[instruction.kind] || "Perform", "perform", () => perform(instruction, number)));
  controls.append(
    button("Confirm", "confirm", () => confirmHazard(instruction, number, false)),
    button("Approve…", "approve", () => approve(number)),
    element("span", "approval-wait", "waiting for another operator"),  // to the sender, in place of Approve…
    button("Retry", "retry", () => act("retry", {instruction: number})),
    button("Skip…", "skip", () => skip(number)),
    button("Go back here…", "go-back", () => goBack(number)),
  );
  if (instruction.kind === "record") controls.append(button("Re-enter…", "correct", () => correctRecord(instruction, number)));
  item.append(controls, element("div", "countdown"), element("div", "mark"), element("div", "detail"), element("div", "raw raw-detail"));
  if (instruction.callee) item.append(buildCallee(instruction.callee, `${number}/`));
  return item;
}

function limitsText(limits) {
  const parts = [];
  if (limits.min !== null) parts.push(`min ${limits.min}`);
  if (limits.max !== null) parts.push(`max ${limits.max}`);
  if (limits.enum) parts.push(`one of ${limits.enum.join(", ")}`);
  return parts.join(", ") || "none";
}

// A called sub-procedure, drawn inside its call with the executive's numbers (call/number).
function buildCallee(callee, prefix) {
  const box = element("ol", "callee");
  for (const step of callee.steps) {
    box.append(element("li", "callee-step", `${prefix}${step.number}. ${step.title} (${callee.title})`), ...step.notices.map(noticeBox));
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
  const choices = record.choices || (record.type === "boolean" ? ["true", "false"] : null);
  if (choices) {
    // no choice made until the operator makes one: Record on an untouched field records nothing
    input = document.createElement("select");
    input.append(new Option("choose…", ""), ...choices.map((choice) => new Option(choice, choice)));
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
  }
  input.required = true;
  input.className = "record-value";
  input.name = record.name;
  input.setAttribute("aria-label", `${record.name} (${record.type})`);
  const submit = button("Record", "record", () => {
    if (input.reportValidity && !input.reportValidity()) return;
    act("enter", {instruction: number, value: typedValue(record.type, input.value)});
  });
  const refused = element("span", "record-error error");
  refused.setAttribute("role", "alert");
  return [element("span", "record-name", `${record.name.replaceAll("_", " ")} (${record.type})`), input, submit, refused];
}

// Where a record's refusal is said: next to its field.
function recordError(number) {
  return document.querySelector(`#procedure li.instruction[data-number="${number}"] > .instruction-controls > .record-error`);
}

function typedValue(type, text) {
  if (type === "integer" && /^-?\d+$/.test(text)) return Number(text);
  if (type === "real" && text.trim() !== "" && !Number.isNaN(Number(text))) return Number(text);
  if (type === "boolean") return text === "true";
  return text;  // the server converts and validates, and says what is wrong
}

async function perform(instruction, number) {
  if ((instruction.hazardous || approvalNeeded(number)) && view.state.hold !== "failure") {
    confirmHazard(instruction, number, true);
    return;
  }
  await act("perform", {instruction: number});
}

// Critical commanding: the current command needs a second operator's approval (and nobody sent it for one yet).
function approvalNeeded(number) {
  const approval = view.state.approval;
  return Boolean(approval) && approval.number === number && approval.state === "needed";
}

// A hazardous command: confirm it is safe to send; under critical commanding the same click sends
// it for a second operator's approval (this operator its sender), and the approval sends it.
function confirmHazard(instruction, number, thenSend) {
  const dialog = $("confirm-dialog");
  const forApproval = approvalNeeded(number);
  $("confirm-text").textContent = forApproval ?
    `${number}: ${sentenceOf(number)}. Send it for a second operator's approval: it is sent once another operator approves it.` :
    `${number}: ${sentenceOf(number)}. Confirm that it is safe to send.`;
  $("confirm-yes").textContent = forApproval ? "Send for approval" : "Confirm";
  dialog.returnValue = "";
  dialog.onclose = async () => {
    if (dialog.returnValue !== "confirm") return;
    await act("confirm", {instruction: number});
    if (thenSend && !forApproval && view.state.mode === "manual") await act("perform", {instruction: number});
  };
  dialog.showModal();
}

// The second operator's approval of a command another operator sent for approval: it is sent at once.
function approve(number) {
  const approval = view.state.approval || {};
  const dialog = $("confirm-dialog");
  $("confirm-text").textContent = `${number}: ${approval.command || sentenceOf(number)}. ` +
    `${approval.sender} sent it for approval. Approve it to send it now.`;
  $("confirm-yes").textContent = "Approve and send";
  dialog.returnValue = "";
  dialog.onclose = async () => {
    if (dialog.returnValue === "confirm") await act("approve", {instruction: number});
  };
  dialog.showModal();
}

async function goBack(number) {
  const answer = await askReason(`Go back to ${number}`, `${number}: ${sentenceOf(number)}. PAX continues from there.`, "Go back");
  if (answer) await act("go_back", {instruction: number, reason: answer.reason});
}

async function correctRecord(instruction, number) {
  const old = (view.state.instructions[number] || {}).value;
  const answer = await askReason(`Re-enter ${instruction.record.name.replaceAll("_", " ")}`,
    `Recorded: ${formatValue(old)}. Both values stay in the audit log.`, "Re-enter", old === undefined ? "" : String(old));
  if (answer) await act("correct_record", {instruction: number, value: typedValue(instruction.record.type, answer.value), reason: answer.reason});
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
  const shownStatus = state.live ? state.status : pastStatus(state);
  $("run-status").textContent = shownStatus;
  $("run-status").dataset.status = shownStatus;
  $("run-mode").textContent = state.mode || "";
  renderVersion(state.version);
  renderWatchers(state);
  $("run-host").textContent = !state.live ? "" : state.hosted_here ? "hosted by this console" : `hosted by ${state.host}`;
  const live = Boolean(state.live) && state.status === "active";
  const mayAct = Boolean(view.me && view.me.may_act) && live;
  for (const id of ["mode-manual", "mode-autonomous"]) {
    const node = $(id);
    node.setAttribute("aria-pressed", String(node.dataset.mode === state.mode));
    node.disabled = !mayAct || node.dataset.mode === state.mode;
  }
  // a pause in manual mode holds automation for when someone switches to autonomous; only then can it continue
  const autonomous = state.mode === "autonomous";
  $("pause").disabled = !mayAct || state.paused;
  // after a halted motion automation would send it again, which cannot work (state.no_retry says why)
  $("continue").disabled = !mayAct || !autonomous || !(state.paused || ["breakpoint", "halted"].includes(state.hold)) ||
    Boolean(state.no_retry);
  $("step").disabled = !mayAct || state.executing || !state.current;
  $("stop").disabled = !mayAct;
  $("halt").disabled = !mayAct;
  $("halt-reason").disabled = !mayAct;
  $("controls").hidden = !state.live;
  renderLink(state);
  const unknown = mayAct && state.hold === "outcome_unknown" && !state.executing;
  const lost = mayAct && state.hold === "control_lost";
  for (const id of ["ask-again", "resolve-succeeded", "resolve-failed"]) $(id).hidden = !unknown;
  $("take-control").hidden = !lost;
  const replan = mayAct && state.hold === "halted" && Boolean(state.replan_from) && !state.executing;
  $("replan").hidden = !replan;
  $("replan").title = replan ? `back to ${state.replan_from}: it plans the motion again from where the arm is, and the run goes on from there` : "";
  // any other halt (nothing was moving, or what moved can be sent again): Continue goes on from here
  const goOn = mayAct && state.hold === "halted" && !state.no_retry && !state.executing;
  $("hold-continue").hidden = !goOn;
  $("hold-continue").textContent = goOn ? "Continue" : "";  // the banner's words are only what can be done now
  $("hold-actions").hidden = !(unknown || lost || replan || goOn);
  $("past-controls").hidden = Boolean(state.live) || !(view.me && view.me.may_act) || shownStatus === "completed";
  const envs = JSON.stringify(state.envs || {});
  const envsChanged = envs !== view.envsSeen;
  view.envsSeen = envs;
  for (const item of document.querySelectorAll("#procedure li.instruction")) renderInstruction(item, state, mayAct, envsChanged);
  renderHold(state);
  renderTelemetry();
  renderCountdowns();
  renderCamera();
  renderTrajectory();
  renderMonitors();
  follow(state);
}

function pastStatus(state) {
  return state.status === "completed" || state.status === "stopped" ? state.status : "interrupted";
}

// The robot link and the audit log: lost since when, with how many commands waiting for their outcome.
function renderLink(state) {
  const link = state.link || {state: "connected"};
  const box = $("robot-link");
  box.dataset.state = link.state;
  const clock = (iso) => new Date(iso).toISOString().slice(11, 19);
  if (state.onboard) {  // the habitat runs it: the banner is what the ground heard, and how old that is
    const news = state.onboard;
    const at = news.at ? `, last reported at ${news.at}` : "";
    const age = news.last_event_age_s == null ? "" : `, event #${news.last_seq} arrived ${news.last_event_age_s.toFixed(1)} s after it happened`;
    box.textContent = link.state === "silent"
      ? `⚠ no news from the habitat since ${clock(link.since)} UTC${at}`
      : `onboard run on the habitat: habitat time ${news.habitat_time ? clock(news.habitat_time) : "—"} UTC${at}${age}`;
  } else if (link.state === "lost") {
    const n = link.in_flight || 0;
    const what = link.quiet ? "no news from the habitat" : "link lost";  // quiet: held, not yet given up
    box.textContent = `⚠ ${what} since ${clock(link.since)} UTC, ${n} command${n === 1 ? "" : "s"} in flight`;
  } else {
    box.textContent = state.live ? "link connected" : "";
  }
  const journal = state.journal || {available: true};
  $("journal").dataset.state = journal.available ? "available" : "unavailable";
  $("journal").textContent = journal.available ? "" :
    `⚠ audit log unavailable${journal.since ? " since " + new Date(journal.since).toISOString().slice(11, 19) + " UTC" : ""}: ${journal.error} (the run waits)`;
}

function renderWatchers(state) {
  const watchers = state.watchers || [];
  $("watchers").textContent = watchers.length ? `watching: ${watchers.map((w) => `${w.user} (${w.role})`).join(", ")}` : "";
}

function renderInstruction(item, state, mayAct, envsChanged) {
  const number = item.dataset.number;
  const running = Boolean(state.live) && state.status === "active";  // controls only on a running run
  const status = (state.statuses && state.statuses[number]) ||
    (state.instructions[number] && state.instructions[number].status) || "pending";
  const details = state.instructions[number] || {};
  const current = state.current === number;
  item.dataset.status = status;
  item.classList.toggle("current", current);
  item.classList.toggle("held", current && Boolean(state.hold) && !["failure", "in_flight", "manual_mode"].includes(state.hold));
  item.classList.toggle("has-breakpoint", state.breakpoints.includes(number));
  const own = (selector) => item.querySelector(`:scope > ${selector}`);  // not those of a called sub-procedure
  if (envsChanged) fillSentence(own(".line > .text"), view.sentences.get(number), (state.envs || {})[frameOf(number)]);
  // an unknown outcome is settled first (ask again, record what the system shows, or skip)
  const unsettled = state.hold === "outcome_unknown";
  const idle = mayAct && current && !state.executing && !unsettled;
  const failed = ["failure", "in_flight", "halted"].includes(state.hold);
  const held = state.mode === "manual" || ["not_automatable", "confirmation", "breakpoint", "paused"].includes(state.hold);
  const kind = [...item.classList].find((c) => c.startsWith("kind-")).slice(5);
  own(".line > .breakpoint").disabled = !mayAct;
  const show = (selector, visible, enabled) => {
    const node = own(`.instruction-controls > ${selector}`);
    if (!node) return;
    node.hidden = !visible;
    node.disabled = !enabled;
  };
  // Send and its kin: on every such instruction in manual mode, on the held one in autonomous mode
  show(".perform", running && (state.mode === "manual" || current), idle && held && !failed);
  // under critical commanding a failed or halted command is sent for approval again before its retry
  show(".confirm", running && current && (state.hold === "confirmation" || approvalNeeded(number)), idle);
  own(".instruction-controls > .confirm").textContent = current && approvalNeeded(number) ? "Send for approval…" : "Confirm";
  const requested = state.approval && state.approval.number === number && state.approval.state === "requested";
  const sentByMe = Boolean(requested) && Boolean(view.me) && state.approval.sender === view.me.user;  // nobody approves their own
  show(".approve", running && current && Boolean(requested) && !sentByMe, idle);
  show(".approval-wait", running && current && sentByMe, false);
  show(".done", running, idle && kind === "manual");
  show(".record", running, idle);
  const input = own(".instruction-controls > .record-value");
  if (input) input.disabled = !idle;
  show(".retry", running && current && failed && !state.no_retry, idle);
  show(".skip", running && current, mayAct && current && !state.executing);
  // back within the current step, to an instruction already done; a record done may be re-entered
  const sameStep = state.current && number !== state.current && stepOf(number) === stepOf(state.current);
  const done = ["completed", "skipped", "failed", "halted"].includes(status);
  show(".go-back", running && sameStep && done, mayAct && !state.executing && !unsettled);
  show(".correct", running && status === "completed", mayAct && !state.executing);
  own(".mark").textContent = markText(number, status, details, current, state);
  const parts = [];
  if (details.result) {
    const lines = (details.result_lines || []).map(([label, text]) => `${label}: ${text}`);
    const outcome = OUTCOME_WORDS[details.result.outcome] || (details.result.success ? "succeeded" : "FAILED");
    parts.push(`Result: ${outcome}${details.result.message ? " — " + details.result.message : ""}` +
      (lines.length ? ` · ${lines.join(" · ")}` : ""));
  }
  if (details.value !== undefined) parts.push(`recorded ${formatValue(details.value)}`);
  if (details.telemetry) {  // the value it decided on, coloured by its limits (and saying so) as it was then
    const seen = details.telemetry;
    const label = item.querySelector(":scope > .line > .telemetry")?.dataset.label || seen.item;
    parts.push(limitedValue(`saw ${label} = ${formatValue(seen.value)}${seen.stale ? " (stale)" : ""}`, seen.stale ? null : seen.limit));
  }
  own(".detail").replaceChildren(...joined(parts));
  own(".raw-detail").textContent = details.sent ? `sent ${details.sent.system}.${details.sent.command}(${formatArgs(details.sent.args)})` : "";
}

function stepOf(number) {
  const local = number.slice(frameOf(number).length);
  return frameOf(number) + local.split(".")[0];
}

// Who did what to an instruction: sent, confirmed or approved, recorded an unknown outcome, re-entered its record.
function attribution(details) {
  const parts = [];
  if (details.sent_by) parts.push(`sent by ${details.sent_by}`);
  if (details.confirmed_by) parts.push(`confirmed by ${details.confirmed_by}`);
  const approved = details.sent && details.sent.approved_by;
  if (approved) parts.push(`sent for approval by ${details.sent.requested_by}, approved by ${approved}`);
  if (details.resolved) parts.push(`outcome recorded as ${details.resolved.outcome} by ${details.resolved.by}: ${details.resolved.reason}`);
  if (details.corrected) {
    const c = details.corrected;
    parts.push(`re-entered by ${c.by}: ${formatValue(c.old)} → ${formatValue(c.value)} (${c.reason})`);
  }
  return parts.length ? ` · ${parts.join(" · ")}` : "";
}

// A command's outcome in words: one that is not known is neither a success nor a failure.
const OUTCOME_WORDS = {succeeded: "succeeded", failed: "FAILED", unknown: "outcome unknown", halted: "halted"};

function markText(number, status, details, current, state) {
  const who = details.actor ? ` by ${details.actor}` : "";
  const when = details.time ? ` at ${new Date(details.time).toLocaleTimeString()}` : "";
  const reason = details.reason ? ` — ${details.reason}` : "";
  const by = attribution(details);
  if (current && state.hold === "outcome_unknown") return `? outcome unknown: neither done nor failed${by}`;
  if (status === "completed") return `✓ completed${who}${when}${by}`;
  if (status === "halted") return `■ halted${who}${when}${by}`;  // why: in the hold banner and the audit log
  if (status === "failed") return current && state.hold === "in_flight" ? `? outcome unknown${reason}` : `✗ failed${who}${when}${reason}${by}`;
  if (status === "skipped") return `⤼ skipped${who}${when}${reason}`;
  if (status === "executing") return `⟳ in progress${who}`;
  if (current && state.hold === "in_flight") return "? outcome unknown: it was in flight when the runner stopped";
  if (current && HOLDS[state.hold] && state.hold !== "manual_mode") return `${HOLDS[state.hold][1]} ${HOLDS[state.hold][2](number)}`;
  return "";
}

function formatArgs(args) {
  return Object.entries(args || {}).map(([name, value]) => `${name}=${formatValue(value)}`).join(", ");
}

// The procedure version the run runs: its release, or a rehearsal (a draft, or a file changed since
// its release, run on a simulator), marked so wherever the run is shown.
function renderVersion(version) {
  const badge = $("run-version");
  badge.hidden = !version;
  if (!version) return;
  const sha = `sha256 ${version.sha256.slice(0, 8)}…`;
  badge.dataset.rehearsal = String(Boolean(version.rehearsal));
  badge.textContent = version.rehearsal ?
    `REHEARSAL · ${version.release ? "release " + version.release : "draft, not released"} · ${sha}` :
    `release ${version.release} · ${sha}`;
  badge.title = version.rehearsal ? "a rehearsal on a simulator: this version was not released for the robot" :
    "the released version of the procedure that this run runs";
  document.body.classList.toggle("rehearsal", Boolean(version.rehearsal));
}

// ---- the hold banner: what is needed, by whom, since when -------------------------------------
const HOLDS = {
  failure: ["failure", "✗", () => "Failed", () => "an operator must retry or skip it"],
  in_flight: ["unknown", "?", () => "Outcome unknown", () => "an operator must check the system, then retry (resend) or skip it"],
  outcome_unknown: ["unknown", "?", () => "Outcome unknown",
    () => "an operator must ask the habitat again, record what the system shows, or skip it"],
  halted: ["halted", "■", () => "Halted", haltedWayOn],
  control_lost: ["failure", "⚑", () => "Robot taken over", () => "this run sends nothing until an operator takes control back"],
  confirmation: ["hold", "⚠", () => "Hazardous command", (state) => state.approval ?
    "an operator must send it for a second operator's approval" : "an operator must confirm it is safe to send"],
  approval: ["hold", "⚠", () => "Waits for a second operator's approval",
    (state) => `an operator other than ${(state.approval || {}).sender} must approve it`],
  operator_input: ["hold", "✎", () => "Needs a value", () => "an operator must enter it"],
  operator_action: ["hold", "☞", () => "Needs an operator", () => "an operator must do it, then mark it Done"],
  not_automatable: ["hold", "☞", () => "Needs an operator", () => "an operator must perform it"],
  breakpoint: ["info", "●", (n) => `Breakpoint at ${n}`, () => "an operator may Continue or Step"],
  paused: ["info", "‖", (n) => `Automation paused at ${n}`, () => "an operator may Continue"],
  manual_mode: ["info", "▶", () => "Manual mode", () => "an operator performs each instruction"],
};

// What an operator may do after a halt: after a halted motion (its plan ended with it) sending it
// again cannot work, so the way on is to plan it again from where the arm is.
function haltedWayOn(state) {
  if (!state.no_retry) return "an operator may retry, continue, skip or stop";
  const replan = state.replan_from ? `re-plan from where the arm is and go on (from ${state.replan_from}), ` : "";
  return `its plan ended with the halt: an operator may ${replan}go back to an earlier instruction, skip it or stop the run`;
}

function renderHold(state) {
  const box = $("hold");
  let tone = "none", icon = "", what = "", text = "", who = "";
  const number = state.current;
  const sentence = number ? `${number}: ${sentenceOf(number)}` : "";
  if (state.error) {
    [tone, icon, what, text] = ["failure", "✗", "Recording failed", state.error];
  } else if (state.status === "completed") {
    [tone, icon, what] = ["done", "✓", "Run completed"];
  } else if (state.status === "stopped" || (!state.live && state.status !== "completed")) {
    const stopped = state.stopped;
    [tone, icon] = ["stopped", "■"];
    what = stopped ? "Run stopped" : "Run interrupted";
    const lost = state.host_lost;
    text = stopped ? `by ${stopped.by}${stopped.reason ? ": " + stopped.reason : ""}` :
      lost ? `${lost.host}, which ran it, went silent at ${new Date(lost.since).toLocaleTimeString()}` :
      "its log ends without an end: the runner stopped";
    who = view.me && view.me.may_act ? "an operator may resume it" : "";
  } else if (state.hold && HOLDS[state.hold]) {
    const [holdTone, holdIcon, title, needed] = HOLDS[state.hold];
    [tone, icon, what, who] = [holdTone, holdIcon, title(number), needed(state)];
    text = ["failure", "in_flight", "outcome_unknown", "control_lost", "approval"].includes(state.hold) ? state.reason :
      state.hold === "halted" ? `by ${state.halted_by}${state.halt_reason ? ": " + state.halt_reason : ""} · ${sentence}` : sentence;
    if (state.hold === "manual_mode" && state.paused) who = "automation is paused for when the run goes autonomous";
  } else if (number) {
    [tone, icon, what, text] = ["run", "⟳", state.executing ? "PAX is performing" : "Running", sentence];
  }
  box.dataset.tone = tone;
  box.querySelector(".hold-icon").textContent = icon;
  box.querySelector(".hold-what").textContent = what;
  box.querySelector(".hold-text").textContent = text;
  box.dataset.since = state.arrived || "";
  box.dataset.who = who;
  renderHoldMeta();
}

function renderHoldMeta() {
  const box = $("hold");
  const state = view.state;
  if (!state) return;
  const parts = [];
  if (box.dataset.who) {
    const operators = (state.watchers || []).filter((w) => w.role === "operator").map((w) => w.user);
    parts.push(box.dataset.who + (state.live && box.dataset.tone !== "done" ?
      (operators.length ? ` (operators watching: ${operators.join(", ")})` : " (no operator is watching this run)") : ""));
  }
  if (box.dataset.since && box.dataset.tone !== "none") {
    const since = new Date(box.dataset.since);
    const end = state.live && !["done", "stopped"].includes(box.dataset.tone) ? Date.now() + view.clockOffset : since.getTime();
    parts.push(`since ${since.toLocaleTimeString()}` + (end > since.getTime() ? ` (${duration((end - since.getTime()) / 1000)})` : ""));
  }
  box.querySelector(".hold-meta").textContent = parts.join(" · ");
}

function duration(seconds) {
  const s = Math.max(0, Math.floor(seconds));
  return s < 60 ? `${s} s` : s < 3600 ? `${Math.floor(s / 60)} min ${s % 60} s` : `${Math.floor(s / 3600)} h ${Math.floor(s % 3600 / 60)} min`;
}

// ---- following the run -----------------------------------------------------------------------
function follow(state) {
  const target = state.current || null;
  if (!$("follow").checked || !target || target === view.followed) return;
  const item = instructionItem(target);
  if (!item) return;
  view.followed = target;
  item.scrollIntoView({block: "center"});
}

$("follow").addEventListener("change", () => {
  view.followed = null;
  if (view.state) follow(view.state);
});
$("show-raw").addEventListener("change", () => document.body.classList.toggle("show-raw", $("show-raw").checked));

// ---- telemetry, countdowns -------------------------------------------------------------------
const CHIP_ICON = {ok: "✓", unexpected: "≠", out: "⚠", red: "⚠", yellow: "▲", stale: "◌", none: ""};

function renderTelemetry() {
  const now = performance.now();
  for (const chip of document.querySelectorAll("#procedure .telemetry")) {
    const reading = view.telemetry.get(chip.dataset.key);
    const label = chip.dataset.label;
    if (!reading) {
      chip.textContent = view.state && view.state.live ? `${label}: no value` : "";
      chip.dataset.state = view.state && view.state.live ? "stale" : "none";
      continue;
    }
    if (reading.error) {
      chip.textContent = `${CHIP_ICON.stale} ${label}: ${reading.error}`;
      chip.dataset.state = "stale";
      continue;
    }
    const check = view.checks[chip.dataset.check];
    const limit = readingLimit(reading);  // its SysRep limits: red or yellow colour the chip, and say so in words
    const state = reading.stale ? "stale" : reading.out ? "out" : limit && limit.state !== "green" ? limit.state :
      check === false ? "unexpected" : "ok";
    const age = reading.age === null || reading.age === undefined ? null : reading.age + (now - reading.receivedAt) / 1000;
    const units = chip.dataset.units ? ` ${chip.dataset.units}` : "";
    const verdict = state === "out" ? ` (outside its limits: ${reading.out})` :
      state === "unexpected" ? ` (expected ${chip.dataset.expected.replace(/^= /, "")})` : "";
    chip.textContent = `${CHIP_ICON[state]} ${label} = ${formatValue(reading.value, reading.item)}${units}` +
      `${limit ? " " + limitWords(limit) : ""}${verdict}` +
      (age === null ? "" : ` · ${age.toFixed(1)} s ago`) + (reading.stale ? " · STALE" : "");
    chip.dataset.state = state;
    chip.dataset.limit = limit ? limit.state : "";
    chip.dataset.stale = String(Boolean(reading.stale));
  }
}

// A verify or wait in progress counts down its timeout from when it started (server's clock).
function renderCountdowns() {
  const state = view.state;
  for (const item of document.querySelectorAll("#procedure li.instruction[data-timeout]")) {
    const box = item.querySelector(":scope > .countdown");
    const details = state && state.instructions[item.dataset.number];
    if (!state || !state.live || item.dataset.status !== "executing" || !details || !details.started) {
      box.textContent = "";
      continue;
    }
    const timeout = Number(item.dataset.timeout);
    const elapsed = (Date.now() + view.clockOffset - new Date(details.started).getTime()) / 1000;
    const left = timeout - elapsed;
    box.textContent = left > 0 ? `◷ ${Math.ceil(left)} s left of ${timeout} s` : `◷ ${timeout} s are up`;
    box.dataset.late = String(left <= 0);
  }
}

setInterval(() => {
  renderTelemetry();
  renderCountdowns();
  renderHoldMeta();
}, 500);

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
  const lines = planTelemetry.map((r) =>
    limitedValue(`${r.item.replaceAll("_", " ")} = ${formatValue(r.value, r.item)}${r.stale ? " (stale)" : ""}`, readingLimit(r)));
  if (!plans.length) {
    box.replaceChildren(...joined(lines), lines.length ? ". " : "", "No end pose yet: it is drawn when a plan result carries one (values.end_pose).");
    return;
  }
  const latest = plans[plans.length - 1];
  const pose = normalizePose(latest.data.values.end_pose);
  if (!pose) {
    box.textContent = `end pose not understood: ${formatValue(latest.data.values.end_pose, "end_pose")}`;
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
  const text = element("p", "pose-text",
    `${latest.instruction}: end pose x ${pose.x.toFixed(3)}, y ${pose.y.toFixed(3)}, z ${pose.z.toFixed(3)} m, ` +
    `yaw ${(pose.yaw * 180 / Math.PI).toFixed(1)}° (top view, robot base at the centre, ±${(100 / scale).toFixed(2)} m shown)`);
  text.append(...joined(["", ...lines]));
  box.append(text);
}

function normalizePose(pose) {
  if (Array.isArray(pose) && pose.length >= 3) return {x: +pose[0], y: +pose[1], z: +pose[2], yaw: +(pose[5] || 0)};
  if (pose && typeof pose === "object" && "x" in pose) return {x: +pose.x, y: +pose.y, z: +(pose.z || 0), yaw: +(pose.yaw || 0)};
  return null;
}
