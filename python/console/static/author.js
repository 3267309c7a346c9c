// Caretaker Author page: palette → drag onto the canvas → typed forms (author_forms.js) → live lint → save.
//
// The page edits a document (elements as JSON: kind, attributes, args, text); the server turns
// it into procedure XML and checks it with the same lint as `caretaker lint`, so every rule of
// meaning lives on the server and problems come back placed on the item they concern.
"use strict";

const $ = (id) => document.getElementById(id);

const author = {
  me: null,
  sysreps: [],          // palette: [{id, name, commands: [{id, label, args}], telemetry}]
  signatures: {},       // file → declared {inputs, outputs} [{name, type}]: what a call passes and reads back
  doc: null,            // the document being edited
  problems: [],
  sections: null,       // per step, what a start there needs ({from, needs}); null while lint finds problems
  checkTimer: null,
  dragging: false,
  paletteKey: null,
};

const KINDS = {
  command: {label: "command", attrs: ["system", "name", "result", "on-failure"], flags: ["hazardous", "automatable"]},
  verify: {label: "verify telemetry", attrs: ["system", "telemetry", "equals", "not-equals", "min", "max", "tolerance", "timeout", "on-failure"], flags: ["automatable"]},
  wait: {label: "wait", attrs: ["seconds", "system", "telemetry", "equals", "timeout"], flags: ["automatable"]},
  record: {label: "record (operator input)", attrs: ["name", "type", "min", "max", "pattern", "one-of"], text: true},
  manual: {label: "manual (operator marks done)", attrs: [], text: true},
  if: {label: "branch (if)", attrs: ["input", "system", "telemetry", "result", "equals", "not-equals", "goto", "else"], flags: ["automatable"]},
  goto: {label: "go to step", attrs: ["step"]},
  call: {label: "call sub-procedure", attrs: ["procedure", "result"]},
  set: {label: "set an output", attrs: []},
  monitor: {label: "monitor (watched while its step runs)", attrs: []},
  note: {label: "note", attrs: [], text: true},
  caution: {label: "caution", attrs: [], text: true},
  warning: {label: "warning", attrs: [], text: true},
};
const NOTICES = new Set(["note", "caution", "warning"]);
const DEFAULTS = {verify: {timeout: "10"}, wait: {seconds: "1"}, record: {name: "", type: "string"}};
// kinds with an optional sentence (records, manual steps and notices are text already)
const SENTENCE = new Set(["command", "verify", "wait", "if", "goto", "call", "set", "monitor"]);

async function api(method, path, body) {
  const headers = body === undefined ? {} : {"Content-Type": "application/json"};
  if (method !== "GET" && author.me) headers["X-CSRF-Token"] = author.me.csrf;
  const response = await fetch(path, {method, headers, body: body === undefined ? undefined : JSON.stringify(body)});
  const data = await response.json().catch(() => ({}));
  if (!response.ok) {
    const error = new Error(data.error || `${response.status} ${response.statusText}`);
    error.status = response.status;
    throw error;
  }
  return data;
}

function element(tag, className, text) {
  const node = document.createElement(tag);
  if (className) node.className = className;
  if (text !== undefined) node.textContent = text;
  return node;
}

// ---- palette ---------------------------------------------------------------------------------
// What can be dragged, and what each drop zone takes.
const NEW_ITEM = "application/x-caretaker-item";  // a palette entry: the spec of a new item
const MOVE_ITEM = "application/x-caretaker-move";  // a card dragged to another place: {step, index}
const MOVE_STEP = "application/x-caretaker-step";  // a step dragged by its handle: its index

function dragSource(node, type, data, effect) {
  node.draggable = true;
  node.addEventListener("dragstart", (event) => {
    author.dragging = true;  // the canvas must not be redrawn under a drag: its drop zones would go
    event.dataTransfer.setData(type, JSON.stringify(data));
    event.dataTransfer.effectAllowed = effect;
  });
  node.addEventListener("dragend", () => {
    author.dragging = false;
    render();
  });
}

function paletteItem(text, spec, detail) {
  const item = element("li", "palette-item", text);
  if (detail) item.append(element("div", "args", detail));
  dragSource(item, NEW_ITEM, spec, "copy");
  return item;
}

function renderPalette() {
  const key = JSON.stringify(author.doc ? author.doc.uses : []);
  if (key === author.paletteKey) return;  // redraw only when the SysReps in use change
  author.paletteKey = key;
  $("palette-kinds").replaceChildren(...Object.entries(KINDS).map(([kind, info]) => {
    const item = paletteItem(info.label, {kind});
    item.dataset.kind = kind;
    return item;
  }));
  const used = new Set(author.doc ? author.doc.uses : []);
  $("palette-sysreps").replaceChildren(...author.sysreps.filter((s) => used.has(s.id)).map((sysrep) => {
    const box = element("section", "palette-sysrep");
    box.dataset.sysrep = sysrep.id;
    box.append(element("h3", "", `${sysrep.name} (${sysrep.id})`));
    const commands = element("ul", "palette-list");
    for (const command of sysrep.commands) {
      const item = paletteItem(command.label, {kind: "command", system: sysrep.id, command: command.id},
        command.args.map((a) => `${a.name}: ${a.type}`).join(", ") || "no arguments");
      item.dataset.command = command.id;
      commands.append(item);
    }
    const telemetry = element("ul", "palette-list");
    for (const item of sysrep.telemetry) {
      const entry = paletteItem(`verify ${item.label}`, {kind: "verify", system: sysrep.id, telemetry: item.id}, item.type);
      entry.dataset.telemetry = item.id;
      telemetry.append(entry);
    }
    box.append(element("div", "args", "commands"), commands, element("div", "args", "telemetry (drops a verify)"), telemetry);
    return box;
  }));
}

function newItem(spec) {
  const item = {kind: spec.kind, attrs: {...(DEFAULTS[spec.kind] || {})}};
  if (spec.kind === "command" || spec.kind === "call") item.args = [];
  if (KINDS[spec.kind].text) item.text = "";
  if (spec.kind === "command" && spec.system) {
    item.attrs.system = spec.system;
    item.attrs.name = spec.command;
    const command = commandOf(spec.system, spec.command);
    item.args = command.args.map((a) => ({name: a.name, value: defaultValue(a)}));
  }
  if (spec.kind === "verify" && spec.system) {
    item.attrs = {system: spec.system, telemetry: spec.telemetry, equals: "", timeout: "10"};
  }
  if (spec.kind === "monitor") item.attrs = newMonitor();
  if (spec.kind === "set") {  // the first declared output, with a value of its type
    const output = author.doc.outputs[0];
    item.attrs.name = output ? output.name : "";
    item.value = defaultValue(output);
  }
  return item;
}

// A new monitor watches the first used SysRep's first item with limits (its red limit), or its first
// item (a condition to fill in); the card's pickers choose another.
function newMonitor() {
  const sysrep = author.sysreps.find((s) => s.id === author.doc.uses[0]);
  const items = sysrep ? sysrep.telemetry : [];
  const watched = items.find((t) => t.limits) || items[0];
  const attrs = {system: sysrep ? sysrep.id : "", telemetry: watched ? watched.id : ""};
  if (watched && watched.limits) attrs.limit = "red";
  else attrs.equals = "";
  return attrs;
}

function commandOf(system, name) {
  const sysrep = author.sysreps.find((s) => s.id === system);
  return sysrep && sysrep.commands.find((c) => c.id === name);
}

// ---- canvas ----------------------------------------------------------------------------------
// A place to drop on: ``handlers`` maps each accepted drag type to what the drop does with its data.
function dropTarget(zone, handlers) {
  const accepts = (event) => Object.keys(handlers).some((type) => event.dataTransfer.types.includes(type));
  zone.addEventListener("dragover", (event) => {
    if (!accepts(event)) return;
    event.preventDefault();
    zone.classList.add("over");
  });
  zone.addEventListener("dragleave", () => zone.classList.remove("over"));
  zone.addEventListener("drop", (event) => {
    event.preventDefault();
    author.dragging = false;
    zone.classList.remove("over");
    for (const [type, handle] of Object.entries(handlers)) {
      const data = event.dataTransfer.getData(type);
      if (data) {
        handle(JSON.parse(data));
        return;
      }
    }
  });
  return zone;
}

function dropZone(stepIndex, itemIndex) {
  const zone = element("div", "drop");
  zone.dataset.step = stepIndex;
  zone.dataset.index = itemIndex;
  const items = () => author.doc.steps[stepIndex].items;
  return dropTarget(zone, {
    [MOVE_ITEM]: (from) => relocate(author.doc.steps[from.step].items, from.index, items(), itemIndex),
    [NEW_ITEM]: (spec) => {
      items().splice(itemIndex, 0, newItem(spec));
      changed();
    },
  });
}

function stepDropZone(stepIndex) {
  const zone = element("li", "drop step-drop");
  zone.dataset.stepIndex = stepIndex;
  return dropTarget(zone, {[MOVE_STEP]: (from) => relocate(author.doc.steps, from, author.doc.steps, stepIndex)});
}

function numbers() {
  // what the executive will number: steps 1, 2, …; instructions n.1, n.2, … (notices unnumbered)
  return author.doc.steps.map((step, s) => {
    let n = 0;
    return step.items.map((item) => (NOTICES.has(item.kind) || item.kind === "monitor" ? null : `${s + 1}.${++n}`));
  });
}

function scope(stepIndex, itemIndex) {
  // names an argument may be bound to at this point: inputs, earlier records, outputs set, results
  const names = author.doc.inputs.map((i) => `\${${i.name}}`);
  author.doc.steps.forEach((step, s) => step.items.forEach((item, i) => {
    if (s > stepIndex || (s === stepIndex && i >= itemIndex)) return;
    if (["record", "set"].includes(item.kind) && item.attrs.name) names.push(`\${${item.attrs.name}}`);
    if (item.kind === "call" && item.attrs.result) {
      for (const output of signature(item.attrs.procedure).outputs) names.push(`\${${item.attrs.result}.${output.name}}`);
    }
    if (item.kind === "command" && item.attrs.result) {
      for (const field of ["id", "instance", "success", "message", "path"]) names.push(`\${${item.attrs.result}.${field}}`);
    }
  }));
  return names;
}

function renderCanvas() {
  const canvas = $("canvas");
  const numbering = numbers();
  canvas.replaceChildren(stepDropZone(0), ...author.doc.steps.flatMap((step, s) => {
    const box = element("li", "canvas-step");
    box.dataset.step = s;
    const header = element("header");
    const handle = element("span", "handle", "⠿");
    handle.title = "drag to move the step";
    dragSource(handle, MOVE_STEP, s, "move");
    header.append(handle, element("span", "number", `${s + 1}.`),
      input("step title", step.attrs.title || "", (v) => { step.attrs.title = v; }, "step-title"),
      input("step id", step.attrs.id || "", (v) => { step.attrs.id = v; }, "step-id"), contingencyField(step),
      button("↑", "move step up", () => move(author.doc.steps, s, -1)),
      button("↓", "move step down", () => move(author.doc.steps, s, 1)),
      button("✕", "delete step", () => { author.doc.steps.splice(s, 1); changed(); }));
    box.append(header, sectionStart(s, numbering), ...problemsAt(s, -1), dropZone(s, 0));
    step.items.forEach((item, i) => box.append(card(item, s, i, numbering[s][i]), dropZone(s, i + 1)));
    return [box, stepDropZone(s + 1)];
  }));
}

// A contingency step is entered only by a go-to (a branch's, a failure's, a monitor's): the flow passes over it.
function contingencyField(step) {
  const label = element("label", "contingency", "contingency");
  const box = document.createElement("input");
  box.type = "checkbox";
  box.checked = ["true", "1"].includes(step.attrs.contingency);
  box.addEventListener("change", () => {
    step.attrs.contingency = box.checked ? "true" : "";
    changed();
  });
  label.prepend(box);
  return label;
}

// What a run started at this step (caretaker run --from) must be given: what only the steps it skips bind.
function sectionStart(s, numbering) {
  const line = element("div", "section-start");
  const section = author.sections && author.sections[s];
  if (!section) {
    line.textContent = "a start here (--from): shown when lint finds no problem";
    return line;
  }
  line.dataset.ok = String(!section.needs.length);
  const read = (need) => (need.at && numbering[need.at[0]] && numbering[need.at[0]][need.at[1]]) || `line ${need.line}`;
  line.textContent = section.needs.length ?
    `a start here (--from ${section.from}) must be given ${section.needs.map((n) => `${n.name} (read at ${read(n)})`).join(", ")}` +
      " with --set NAME=VALUE" :
    `a run may start here: --from ${section.from}`;
  return line;
}

// Problems placed on a step (i = -1), an item, or an output (s = "outputs", i its index).
function problemsAt(s, i) {
  return author.problems.filter((p) => p.at && p.at[0] === s && p.at[1] === i).map((p) => element("div", "problem", `line ${p.line}: ${p.message}`));
}

// Typing updates the document and schedules a check; leaving the field redraws the canvas.
function edits(node, apply) {
  node.addEventListener("input", () => { if (apply() !== false) scheduleCheck(); });
  node.addEventListener("change", () => { if (apply() !== false) changed(); });
}

function input(label, value, onChange, className) {
  const node = document.createElement("input");
  node.value = value;
  node.setAttribute("aria-label", label);
  node.placeholder = label;
  if (className) node.className = className;
  edits(node, () => onChange(node.value));
  return node;
}

function button(text, title, onClick) {
  const node = element("button", "small", text);
  node.type = "button";
  node.title = title;
  node.setAttribute("aria-label", title);
  node.addEventListener("click", onClick);
  return node;
}

// Move entry ``fromIndex`` of ``fromList`` to place ``toIndex`` of ``toList`` (places counted before the move).
function relocate(fromList, fromIndex, toList, toIndex) {
  const [entry] = fromList.splice(fromIndex, 1);
  // taking the entry out shifts the places after it in its own list
  toList.splice(fromList === toList && fromIndex < toIndex ? toIndex - 1 : toIndex, 0, entry);
  changed();
}

function move(list, index, delta) {
  const target = index + delta;
  if (target < 0 || target >= list.length) return;
  [list[index], list[target]] = [list[target], list[index]];
  changed();
}

// ---- document, checking, saving --------------------------------------------------------------
function renderAttributes() {
  for (const node of document.querySelectorAll(".proc-attrs input[data-attr]")) node.value = author.doc.attrs[node.dataset.attr] || "";
  $("proc-description").value = author.doc.description || "";
  renderDeclared("inputs");
  renderDeclared("outputs");
  $("proc-uses").replaceChildren(element("span", "", "uses: "), ...author.sysreps.map((sysrep) => {
    const label = element("label", "", sysrep.id);
    const box = document.createElement("input");
    box.type = "checkbox";
    box.value = sysrep.id;
    box.checked = author.doc.uses.includes(sysrep.id);
    box.addEventListener("change", () => {
      author.doc.uses = author.sysreps.map((s) => s.id).filter((id) => id === sysrep.id ? box.checked : author.doc.uses.includes(id));
      changed();
    });
    label.prepend(box);
    return label;
  }));
}

function render() {
  renderAttributes();
  renderPalette();
  renderCanvas();
  $("problems").replaceChildren(...author.problems.map((p) => element("li", "", `line ${p.line}:${p.col}: ${p.message}`)));
}

function changed() {
  render();
  scheduleCheck();
}

function scheduleCheck() {
  clearTimeout(author.checkTimer);
  $("check-state").textContent = "checking…";
  delete $("check-state").dataset.ok;
  author.checkTimer = setTimeout(check, 250);
}

function editing() {
  const active = document.activeElement;
  return active && active.closest("#canvas, .proc-attrs") && ["INPUT", "TEXTAREA"].includes(active.tagName);
}

async function check() {
  const sent = JSON.stringify(author.doc);
  try {
    const result = await api("POST", "/api/author/check", {document: author.doc});
    if (JSON.stringify(author.doc) !== sent) return;  // edited meanwhile: a newer check follows
    author.problems = result.problems;
    author.sections = result.sections;
    $("xml").textContent = result.xml;
    $("check-state").textContent = result.problems.length ? `${result.problems.length} problem(s)` : "lint: no problems";
    $("check-state").dataset.ok = String(!result.problems.length);
    if (editing() || author.dragging) {  // keep the field being typed in / the drop zones; redrawn after
      $("problems").replaceChildren(...author.problems.map((p) => element("li", "", `line ${p.line}:${p.col}: ${p.message}`)));
    } else {
      render();
    }
  } catch (error) {
    $("author-error").textContent = error.message;
  }
}

function blank() {
  return {attrs: {id: "new_procedure", title: "New procedure", version: "1"}, description: "", uses: [], inputs: [], outputs: [],
          steps: [{attrs: {title: "First step"}, items: []}]};
}

for (const node of document.querySelectorAll(".proc-attrs input[data-attr]")) {
  edits(node, () => { author.doc.attrs[node.dataset.attr] = node.value; });
}
edits($("proc-description"), () => { author.doc.description = $("proc-description").value; });
$("add-step").addEventListener("click", () => {
  author.doc.steps.push({attrs: {title: `Step ${author.doc.steps.length + 1}`}, items: []});
  changed();
});
$("new").addEventListener("click", () => { author.doc = blank(); $("save-name").value = ""; changed(); });
$("open").addEventListener("click", async () => {
  $("author-error").textContent = "";
  try {
    const name = $("open-name").value;
    author.doc = await api("GET", `/api/author/procedures/${encodeURIComponent(name)}`);
    author.version = null;  // the bar shows this file's version, or none while lint refuses it
    renderVersion();
    $("save-name").value = name;
    changed();
    await showVersion(name);
  } catch (error) {
    $("author-error").textContent = error.message;
  }
});
async function save(replace) {
  const name = $("save-name").value.trim();
  const result = await api("POST", "/api/author/save", {name, document: author.doc, replace});
  $("check-state").textContent = `saved ${result.saved}`;
  $("check-state").dataset.ok = "true";
  await showVersion(result.saved);
}

// ---- released versions: the file on the shelf, as runs will run it --------------------------
// A second operator (not who saved it, not who asked) reviews a version and releases it; operators
// run released versions, and a draft only as a rehearsal on a simulator.
async function showVersion(name) {
  author.version = await api("GET", `/api/author/procedures/${encodeURIComponent(name)}/version`);
  renderVersion();
}

function renderVersion() {
  const version = author.version;
  const box = $("release-state");
  $("release-bar").hidden = !version;
  if (!version) return;
  const me = author.me.user;
  const sha = `sha256 ${version.sha256.slice(0, 8)}…`;
  const release = version.release;
  let text = version.released ? `release ${release.number} (released by ${release.released_by}` +
    `${release.requested_by ? ", asked by " + release.requested_by : ""}) · ${sha}` :
    release ? `changed since release ${release.number} (sha256 ${release.sha256.slice(0, 8)}… → ${version.sha256.slice(0, 8)}…): a draft` :
    `draft, never released · ${sha}`;
  if (!version.released && version.requested_by) text += ` · ${version.requested_by} asks for its release`;
  box.textContent = `${version.name}: ${text}`;
  box.dataset.released = String(version.released);
  const mayAct = author.me.may_act && !version.released;
  $("ask-release").hidden = !mayAct || Boolean(version.requested_by);
  const mine = [version.requested_by, version.saved_by].includes(me);
  $("release").hidden = !mayAct || !version.requested_by;
  $("release").disabled = mine;
  $("release").title = mine ? "a second operator reviews and releases what you saved or asked for" :
    "you reviewed this version: release it for operators to run";
}

async function releaseAction(action) {
  $("author-error").textContent = "";
  try {
    author.version = await api("POST", `/api/author/procedures/${encodeURIComponent(author.version.name)}/release`,
      {action, sha256: author.version.sha256});
    renderVersion();
  } catch (error) {
    $("author-error").textContent = error.message;
  }
}
$("ask-release").addEventListener("click", () => releaseAction("request"));
$("release").addEventListener("click", () => releaseAction("release"));

$("save").addEventListener("click", async () => {
  $("author-error").textContent = "";
  try {
    await save(false);
  } catch (error) {
    if (error.status !== 409) {
      $("author-error").textContent = error.message;
      return;
    }
    // the file exists: replace it only when the author says so
    const dialog = $("replace-dialog");
    $("replace-name").textContent = $("save-name").value.trim();
    dialog.returnValue = "";
    dialog.onclose = async () => {
      if (dialog.returnValue !== "replace") {
        $("author-error").textContent = "not saved: the file exists and was kept";
        return;
      }
      try {
        await save(true);
      } catch (again) {
        $("author-error").textContent = again.message;
      }
    };
    dialog.showModal();
  }
});

async function start() {
  try {
    author.me = await api("GET", "/api/session");
  } catch (error) {
    $("signed-out").hidden = false;
    return;
  }
  $("who").textContent = `${author.me.user} (${author.me.role})`;
  $("save").disabled = !author.me.may_act;
  const palette = await api("GET", "/api/author/palette");
  author.sysreps = palette.sysreps;
  author.signatures = palette.signatures;
  $("procedure-files").replaceChildren(...palette.procedures.map((name) => new Option(name, name)));
  $("open-name").replaceChildren(...palette.procedures.map((name) => new Option(name, name)));
  author.doc = blank();
  $("author-view").hidden = false;
  changed();
}

start();
