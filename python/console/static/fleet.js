// The fleet at a glance: every robot and its live run, whoever hosts it, the ones that need an operator first
// (console/fleet.py orders them), pushed on the runs list's socket whenever a row changes. A row opens its run
// here, where the operator acts on it as on any run. Names and words from the habitat are shown as text
// (textContent), never as markup.
"use strict";

// Each robot keeps its row and its run's link across pushes: a busy fleet is pushed every second or so (each
// habitat's "last heard"), and a link replaced as the operator clicks it would swallow the click.
const fleetRows = new Map();

function fleetRow(robot) {
  let row = fleetRows.get(robot.robot);
  if (!row) {
    row = element("li", "fleet-robot");
    row.runLink = element("a", "");
    fleetRows.set(robot.robot, row);
  }
  row.dataset.robot = robot.robot;
  row.dataset.urgency = robot.urgency;
  row.classList.toggle("open", Boolean(robot.run_id) && robot.run_id === view.runId);
  const name = element("strong", "", robot.robot);
  const state = element("span", "fleet-state", robot.state);
  const head = element("span", "fleet-line");
  head.append(name, " ", state);
  const parts = [head];
  if (robot.run_id) {
    const open = row.runLink;
    if (open.textContent !== robot.run_id) {
      open.textContent = robot.run_id;
      open.href = `#run=${encodeURIComponent(robot.run_id)}`;
    }
    const where = robot.instruction ? ` · at ${robot.instruction}` : "";
    parts.push(open, element("span", "meta", `${robot.procedure}${where} · ${robot.mode}, ${robot.started_by}` +
      `${robot.onboard ? " · onboard" : ""} · ${robot.host}`));
  }
  if (robot.needs) parts.push(element("span", "fleet-needs", `waits for: ${robot.needs}`));
  if (robot.link && robot.link !== "connected") parts.push(element("span", "fleet-link", `link: ${robot.link}`));
  if (robot.heard) parts.push(element("span", "meta", `last heard ${new Date(robot.heard).toLocaleTimeString()}`));
  if (robot.limits_out.length) parts.push(element("span", "fleet-limits", robot.limits_out.join(" · ")));
  row.replaceChildren(...parts);
  return row;
}

function showFleet(robots) {
  $("fleet-panel").hidden = robots.length === 0;
  const rows = robots.map(fleetRow);
  for (const robot of fleetRows.keys()) {
    if (!robots.some((r) => r.robot === robot)) fleetRows.delete(robot);
  }
  const list = $("fleet-list");
  if (rows.length !== list.children.length || rows.some((row, i) => list.children[i] !== row)) {
    list.replaceChildren(...rows);  // the order changed: the same rows, moved
  }
  const waiting = robots.filter((r) => r.urgency === 0).length;
  $("fleet-summary").textContent = `${robots.length} robots` + (waiting ? ` · ${waiting} wait for an operator` : "");
}
