// Attach, on the runs list: a new supervising runner for an onboard run whose supervisor is gone
// (it stopped or died; the habitat runs on). The server offers it in the run's line (`unsupervised`);
// only operators are shown the button, and the server refuses anyone else. A refusal (another
// supervisor holds the run, named) is shown under the list.
"use strict";

function attachButton(run) {
  const button = element("button", "attach small", "Attach…");
  button.type = "button";
  button.title = `start a supervising runner for this onboard run on this console's host ` +
    `(${run.unsupervised.supervisor}, which supervised it, is gone); it catches the record up from the habitat`;
  button.addEventListener("click", () => attachRun(run.run_id, button));
  return button;
}

// The attach answers once the new runner follows the run (a round trip to the habitat or two):
// the run then shows live, hosted by that runner.
async function attachRun(runId, button) {
  $("runs-error").textContent = "";
  if (button) button.disabled = true;
  try {
    await api("POST", `/api/runs/${encodeURIComponent(runId)}/attach`);
    const shown = `#run=${encodeURIComponent(runId)}`;
    if (location.hash === shown) await openRun(runId);  // open already, as a past run: open it live
    else location.hash = shown;  // opens it
    await loadRuns();
  } catch (error) {
    $("runs-error").textContent = error.message;
    if (button) button.disabled = false;
  }
}
