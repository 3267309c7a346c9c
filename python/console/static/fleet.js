// The fleet at a glance: every robot and its live run, whoever hosts it, the ones that need an operator first
// (console/fleet.py orders them), pushed on the runs list's socket whenever a row changes. A row opens its run
// here, where the operator acts on it as on any run. Names and words from the habitat are shown as text
// (textContent), never as markup.
"use strict";

function fleetRow(robot) {
  const row = element("li", "fleet-robot");
  row.dataset.robot = robot.robot;
  row.dataset.urgency = robot.urgency;
  row.classList.toggle("open", Boolean(robot.run_id) && robot.run_id === view.runId);
  const name = element("strong", "", robot.robot);
  const state = element("span", "fleet-state", robot.state);
  const head = element("span", "fleet-line");
  head.append(name, " ", state);
  row.append(head);
  if (robot.run_id) {
    const open = element("a", "", robot.run_id);
    open.href = `#run=${encodeURIComponent(robot.run_id)}`;
    const where = robot.instruction ? ` · at ${robot.instruction}` : "";
    row.append(open, element("span", "meta", `${robot.procedure}${where} · ${robot.mode}, ${robot.started_by}` +
      `${robot.onboard ? " · onboard" : ""} · ${robot.host}`));
  }
  if (robot.needs) row.append(element("span", "fleet-needs", `waits for: ${robot.needs}`));
  if (robot.link && robot.link !== "connected") row.append(element("span", "fleet-link", `link: ${robot.link}`));
  if (robot.heard) row.append(element("span", "meta", `last heard ${new Date(robot.heard).toLocaleTimeString()}`));
  if (robot.limits_out.length) row.append(element("span", "fleet-limits", robot.limits_out.join(" · ")));
  return row;
}

function showFleet(robots) {
  $("fleet-panel").hidden = robots.length === 0;
  $("fleet-list").replaceChildren(...robots.map(fleetRow));
  const waiting = robots.filter((r) => r.urgency === 0).length;
  $("fleet-summary").textContent = `${robots.length} robots` + (waiting ? ` · ${waiting} wait for an operator` : "");
}
