// Caretaker Author page: the form of each card on the canvas, and of the procedure's inputs and
// outputs, typed by the SysReps and by the procedure itself (its steps, outputs, what is in scope).
//
// A form edits one element of the document in place; lint on the server says what is wrong with
// it. A choice the file holds that the page does not offer (an unknown telemetry item, a go-to to
// no step) stays selected, so opening and saving changes nothing and the problem shows on its card.
"use strict";

const TYPES = ["string", "boolean", "integer", "real"];
const CONDITION = ["equals", "not-equals", "min", "max", "tolerance"];  // a monitor's test, without a limit

function card(item, s, i, number) {
  const box = element("div", `card kind-${item.kind}`);
  box.dataset.number = number || "";
  box.dataset.kind = item.kind;
  const problems = problemsAt(s, i);
  if (problems.length) box.classList.add("has-problem");
  const title = item.kind === "command" ? `${item.attrs.system}.${item.attrs.name}` :
    item.kind === "monitor" ? `watch ${item.attrs.system}.${item.attrs.telemetry}` : KINDS[item.kind].label;
  const header = element("header");
  header.append(element("span", "number", number || ""), element("span", "title", title),
    button("↑", "move up", () => move(author.doc.steps[s].items, i, -1)),
    button("↓", "move down", () => move(author.doc.steps[s].items, i, 1)),
    button("✕", "delete", () => { author.doc.steps[s].items.splice(i, 1); changed(); }));
  header.title = "drag to move";  // the header is the handle: the fields stay selectable
  dragSource(header, MOVE_ITEM, {step: s, index: i}, "move");
  const fields = element("div", "fields");
  const info = KINDS[item.kind];
  for (const name of info.attrs) {
    if (item.kind === "command" && (name === "system" || name === "name")) continue;
    fields.append(attrField(item, name));
  }
  for (const flag of info.flags || []) fields.append(flagField(item, flag));
  if (item.kind === "command") {
    const command = commandOf(item.attrs.system, item.attrs.name);
    for (const arg of item.args) fields.append(argField(arg, command && command.args.find((a) => a.name === arg.name), s, i));
  }
  if (item.kind === "call") {
    const declared = signature(item.attrs.procedure).inputs;
    for (const arg of item.args) {
      fields.append(argField(arg, declared.find((d) => d.name === arg.name), s, i, () => {
        item.args.splice(item.args.indexOf(arg), 1);
        changed();
      }));
    }
    fields.append(button("+ argument", "add an argument", () => { item.args.push({name: "", value: ""}); changed(); }));
  }
  if (item.kind === "monitor") fields.append(...monitorFields(item));
  if (item.kind === "set") fields.append(...setFields(item, s, i));
  if (SENTENCE.has(item.kind)) fields.append(sentenceField(item));
  if (info.text) {
    const text = document.createElement("textarea");
    text.value = item.text || "";
    text.setAttribute("aria-label", `${item.kind} text`);
    text.className = "item-text";
    edits(text, () => { item.text = text.value; });
    fields.append(text);
  }
  box.append(header, fields, ...problems);
  return box;
}

function attrField(item, name) {
  if (name === "type") return selectField(item.attrs, name, TYPES.map((type) => [type, type]), "string");
  const label = element("label", "", name);
  const node = document.createElement("input");
  node.value = item.attrs[name] || "";
  node.dataset.attr = name;
  if (name === "procedure") {
    node.setAttribute("list", "procedure-files");
    node.addEventListener("change", () => declareArgs(item));  // before edits() redraws the card
  }
  edits(node, () => { item.attrs[name] = node.value; });
  label.append(node);
  return label;
}

// A call names a known procedure: it gets a row for each input that procedure declares.
function declareArgs(item) {
  for (const input of signature(item.attrs.procedure).inputs) {
    if (!item.args.some((a) => a.name === input.name)) item.args.push({name: input.name, value: defaultValue(input)});
  }
}

function defaultValue(spec) {
  if (!spec || spec.type === "string") return "";
  return spec.type === "boolean" ? "false" : "0";
}

function flagField(item, flag) {
  const label = element("label", "", flag);
  const box = document.createElement("input");
  box.type = "checkbox";
  box.dataset.flag = flag;
  box.checked = flag === "automatable" ? item.attrs.automatable !== "false" : item.attrs[flag] === "true";
  box.addEventListener("change", () => {
    if (flag === "automatable") item.attrs.automatable = box.checked ? "" : "false";  // true is the default
    else item.attrs[flag] = box.checked ? "true" : "";
    changed();
  });
  label.prepend(box);
  return label;
}

// One argument: a control typed by the SysRep (or the called procedure's inputs), or a binding to
// something in scope. An argument nothing declares gets its name typed; call arguments can go.
function argField(arg, spec, s, i, remove) {
  const box = element("span", "arg");
  box.dataset.arg = arg.name;
  if (spec || !remove) {
    box.append(element("span", "", `${arg.name}${spec ? ` (${spec.type})` : ""}`));
  } else {
    const name = input("argument name", arg.name, (v) => { arg.name = v; }, "arg-name");
    box.append(name);
  }
  const bound = /^\$\{[^}]+\}$/.test(arg.value);
  let control;
  if (bound || !spec) {
    control = document.createElement("input");
    control.value = arg.value;
    control.readOnly = bound;
  } else if (spec.type === "boolean") {
    control = document.createElement("input");
    control.type = "checkbox";
    control.checked = arg.value === "true";
  } else {
    control = document.createElement("input");
    if (spec.type === "integer" || spec.type === "real") {
      control.type = "number";
      control.step = spec.type === "integer" ? "1" : "any";
      if (spec.min != null) control.min = spec.min;
      if (spec.max != null) control.max = spec.max;
    }
    control.value = arg.value;
  }
  control.className = "arg-value";
  control.setAttribute("aria-label", arg.name);
  edits(control, () => {
    if (control.type === "checkbox") arg.value = control.checked ? "true" : "false";
    else if (control.type === "number" && !control.checkValidity()) return false;  // the browser shows why
    else arg.value = control.value;
  });
  const bind = document.createElement("select");
  bind.className = "arg-bind";
  bind.setAttribute("aria-label", `bind ${arg.name}`);
  bind.append(new Option(bound ? "literal value" : "bind to…", ""));
  const names = scope(s, i);
  if (bound && !names.includes(arg.value)) names.push(arg.value);  // a value the page cannot list (a result's own field)
  for (const name of names) bind.append(new Option(name, name));
  if (bound) bind.value = arg.value;
  bind.addEventListener("change", () => {
    arg.value = bind.value || defaultValue(spec);
    changed();
  });
  box.append(control, bind);
  if (remove) box.append(button("✕", `remove argument ${arg.name}`, remove));
  return box;
}

// The inputs and outputs a procedure file declares, as the palette read them (none for an unknown file).
function signature(file) {
  return author.signatures[file] || {inputs: [], outputs: []};
}

// A choice of ``attrs[name]`` among ``options`` ([value, label]; ``fallback`` when the attribute is
// not written). A value not among them stays, marked, so it is saved as opened and lint names it.
function selectField(attrs, name, options, fallback = "", then = () => {}) {
  const label = element("label", "", name);
  const node = document.createElement("select");
  const value = attrs[name] ?? fallback;
  const shown = options.some(([v]) => v === value) || value === "" ? options : [...options, [value, `${value} (not one of these)`]];
  for (const [v, text] of shown) node.append(new Option(text, v));
  node.value = value;
  node.dataset.attr = name;
  node.addEventListener("change", () => {
    attrs[name] = node.value;
    then();
    changed();
  });
  label.append(node);
  return label;
}

// How an instruction or monitor reads (optional). A <set>'s content is its value, so its sentence
// is its text attribute; every other kind writes it as a <text> element.
function sentenceField(item) {
  const inAttribute = item.kind === "set";
  const node = document.createElement("input");
  node.value = (inAttribute ? item.attrs.text : item.text) || "";
  node.placeholder = "how it reads (optional: made from the SysRep's labels when empty)";
  node.setAttribute("aria-label", `${item.kind} sentence`);
  node.className = "item-sentence";
  edits(node, () => {
    if (inAttribute) item.attrs.text = node.value;
    else item.text = node.value;
  });
  return node;
}

// A monitor: an item of a used SysRep, watched against its SysRep limit or a condition, while its
// step runs or to the procedure's end; on violation the run halts, holds, or halts and goes to a step.
function monitorFields(item) {
  const items = (author.sysreps.find((s) => s.id === item.attrs.system) || {telemetry: []}).telemetry;
  const watched = items.find((t) => t.id === item.attrs.telemetry);
  const fields = [
    selectField(item.attrs, "system", author.doc.uses.map((id) => [id, id]), "", () => {
      const chosen = author.sysreps.find((s) => s.id === item.attrs.system);
      if (chosen && !chosen.telemetry.some((t) => t.id === item.attrs.telemetry)) {
        item.attrs.telemetry = chosen.telemetry.length ? chosen.telemetry[0].id : "";
      }
    }),
    selectField(item.attrs, "telemetry", items.map((t) => [t.id, `${t.label} (${t.type}${t.limits ? ", has limits" : ""})`])),
    watchField(item),
  ];
  if ("limit" in item.attrs) {
    const limits = (watched && watched.limits) || {};
    fields.push(selectField(item.attrs, "limit", ["red", "yellow"].map((state) =>
      [state, limits[state] ? limits[state] : `${state} (the SysRep states none)`])));
  } else {
    fields.push(...CONDITION.map((name) => attrField(item, name)));
  }
  const goes = author.doc.steps.map((step, n) =>
    [`goto:${step.attrs.id || n + 1}`, `halt, go to step ${n + 1}${step.attrs.title ? ` (${step.attrs.title})` : ""}`]);
  const persistence = attrField(item, "persistence");
  persistence.querySelector("input").placeholder = "as its SysRep says; 3 (samples) or 2 s";
  fields.push(selectField(item.attrs, "scope", [["step", "while its step runs"], ["procedure", "from its step to the end"]], "step"),
    selectField(item.attrs, "on-violation", [["halt", "halt"], ["hold", "hold"], ...goes], "halt"), persistence);
  return fields;
}

// Whether a monitor watches its item's SysRep limit or a condition: switching drops the other's attributes.
function watchField(item) {
  const label = element("label", "", "watch");
  const node = document.createElement("select");
  node.dataset.field = "watch";
  node.append(new Option("its SysRep limit", "limit"), new Option("a condition", "condition"));
  node.value = "limit" in item.attrs ? "limit" : "condition";
  node.addEventListener("change", () => {
    for (const name of ["limit", ...CONDITION]) delete item.attrs[name];
    if (node.value === "limit") item.attrs.limit = "red";
    changed();
  });
  label.append(node);
  return label;
}

// A <set>: a declared output, and its value, typed by the output (a literal, or bound to a name in scope).
function setFields(item, s, i) {
  const outputs = author.doc.outputs;
  const declared = outputs.find((o) => o.name === item.attrs.name);
  const value = {name: "value", get value() { return item.value || ""; }, set value(text) { item.value = text; }};
  return [selectField(item.attrs, "name", outputs.map((o) => [o.name, `${o.name} (${o.type || "string"})`])),
    argField(value, declared && {type: declared.type || "string"}, s, i)];
}

// The values the procedure takes (inputs) and hands back to its caller (outputs): a name and a type each.
function renderDeclared(kind) {
  const list = author.doc[kind];
  const what = kind.slice(0, -1);
  $(`proc-${kind}`).replaceChildren(element("span", "", `${kind}: `), ...list.map((declared, n) => {
    const row = element("span", "declared");
    row.dataset.index = n;
    const problems = problemsAt(kind, n);
    if (problems.length) row.classList.add("has-problem");
    row.append(input(`${what} name`, declared.name || "", (v) => { declared.name = v; }, "declared-name"),
      selectField(declared, "type", TYPES.map((type) => [type, type]), "string"),
      button("✕", `remove ${what} ${declared.name || ""}`.trim(), () => { list.splice(n, 1); changed(); }), ...problems);
    return row;
  }), button(`+ ${what}`, `add an ${what}`, () => { list.push({name: "", type: "string"}); changed(); }));
}
