// Agents' proposals: every console lists them: the procedure and its release, the robot, the values the agent
// gives its records, its reason, and the telemetry it cited as read then and now. An operator accepts one (the
// run starts under their name, as from the start form, on the habitat if they tick it) or declines it with a
// reason the agent reads back. Observers see them only; the server refuses anyone else's answer.
// Everything an agent wrote is shown as text (textContent), never as markup.
"use strict";

const PROPOSALS_POLL_MS = 3000;  // proposals come from agents' processes, which push nothing: read again this often
const PROPOSAL_STATE_WORDS = {open: "waits for an operator", accepted: "accepted", declined: "declined",
  withdrawn: "withdrawn by its agent", expired: "expired unanswered"};

async function loadProposals() {
  clearTimeout(view.proposalsTimer);
  if (!view.me) return;
  try {
    const {proposals} = await api("GET", "/api/proposals");
    showProposals(proposals);
    $("proposals-error").textContent = "";
  } catch (error) {
    $("proposals-error").textContent = `proposals: ${error.message}`;
  }
  if (view.me) view.proposalsTimer = setTimeout(loadProposals, PROPOSALS_POLL_MS);
}

function showProposals(proposals) {
  $("proposals-panel").hidden = proposals.length === 0;
  const busy = document.activeElement && $("proposal-list").contains(document.activeElement);
  if (busy) return;  // an operator is choosing in a card: the next read redraws it
  $("proposal-list").replaceChildren(...proposals.map(proposalCard));
}

function citedLine(cited) {
  const units = cited.units ? ` ${cited.units}` : "";
  const then = `${cited.then.value ?? "no value"}${units} (${cited.then.state}) when proposed`;
  const now = cited.now ? `now ${cited.now.value ?? "no value"}${units} (${cited.now.state})` : "now unknown";
  const line = element("li", "cited", `${cited.system}.${cited.item}: ${then} · ${now}`);
  line.dataset.state = cited.now ? cited.now.state : "unknown";
  return line;
}

function proposalCard(p) {
  const card = element("li", "proposal");
  card.dataset.proposalId = p.id;
  card.dataset.state = p.state;
  card.append(element("strong", "", `${p.agent} proposes ${p.procedure_file} (release ${p.release}) on ${p.robot}`));
  card.append(element("q", "reason", p.reason));
  const values = Object.entries(p.inputs);
  if (values.length) card.append(element("span", "meta", "values: " + values.map(([k, v]) => `${k} = ${v}`).join(", ")));
  if (p.cited.length) {
    const list = element("ul", "cited-list");
    list.append(...p.cited.map(citedLine));
    card.append(list);
  }
  if (p.telemetry_error) card.append(element("span", "error", p.telemetry_error));
  let state = PROPOSAL_STATE_WORDS[p.state] || p.state;
  if (p.closed_by && p.state !== "withdrawn") state += ` by ${p.closed_by}`;
  if (p.state === "open") state += ` · expires ${new Date(p.expires).toLocaleTimeString()}`;
  const status = element("span", "meta proposal-state", state);
  card.append(status);
  if (p.answer) card.append(element("span", "meta", p.state === "open" ? p.answer : `“${p.answer}”`));
  if (p.run_id) {
    const run = element("a", "", `run ${p.run_id}`);
    run.href = `#run=${encodeURIComponent(p.run_id)}`;
    card.append(run);
  }
  if (p.state === "open" && view.me && view.me.may_act) card.append(proposalAnswers(p));
  return card;
}

function proposalAnswers(p) {
  const form = element("form", "proposal-answers");
  const mode = element("select");
  mode.name = "mode";
  mode.append(new Option("manual", "manual"), new Option("autonomous", "autonomous"));
  const onboard = element("input");
  onboard.type = "checkbox";
  onboard.name = "onboard";
  const onboardLabel = element("label", "", " on the habitat");
  onboardLabel.prepend(onboard);
  // on the habitat, commands that need approval go up approved by a second operator (as from the start form)
  const approver = element("input");
  approver.name = "approver";
  approver.placeholder = "second operator";
  approver.autocomplete = "off";
  const password = element("input");
  password.name = "approver_password";
  password.type = "password";
  password.placeholder = "their password";
  password.autocomplete = "off";
  approver.hidden = password.hidden = true;
  onboard.addEventListener("change", () => { approver.hidden = password.hidden = !onboard.checked; });
  const accept = element("button", "accept", "Accept and start");
  accept.type = "submit";
  const decline = element("button", "decline", "Decline…");
  decline.type = "button";
  const error = element("span", "error");
  error.setAttribute("role", "alert");
  form.append(mode, onboardLabel, approver, password, accept, decline, error);
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    accept.disabled = decline.disabled = true;
    try {
      const second = onboard.checked && approver.value ? {approver: approver.value, approver_password: password.value} : {};
      const {run_id: runId} = await api("POST", `/api/proposals/${p.id}/accept`,
        {mode: mode.value, onboard: onboard.checked, ...second});
      location.hash = `#run=${encodeURIComponent(runId)}`;
    } catch (failed) {
      error.textContent = failed.message;
      accept.disabled = decline.disabled = false;
    }
    document.activeElement?.blur();
    loadProposals();
  });
  decline.addEventListener("click", async () => {
    const answer = await askReason(`Decline proposal ${p.id}`,
      `${p.agent} reads your reason back with the proposal.`, "Decline");
    if (!answer) return;
    try {
      await api("POST", `/api/proposals/${p.id}/decline`, {reason: answer.reason});
    } catch (failed) {
      error.textContent = failed.message;
      return;
    }
    document.activeElement?.blur();
    loadProposals();
  });
  return form;
}
