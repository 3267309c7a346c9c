// Actions on their way to a far run: an onboard run's habitat answers a round trip of light time
// later, minutes at Mars. The server answers such an action at once with "on its way" (its request,
// the ground's time its answer is due, and the time after which none can come); this module shows
// it under the run's controls and asks /api/runs/ID/actions/REQUEST what became of it until then:
// "on its way, answer expected at T", "outcome unknown" once T passed with no answer (still
// listening: a late answer is shown), then the habitat's answer. Times are the ground's, in UTC.
"use strict";

const NEWS_POLL_MS = 1000;

const newsClock = (epoch) => new Date(epoch * 1000).toISOString().slice(11, 19);

// What one line says of an action, from what the server knows of it (ActionRequests.progress).
function newsText(known) {
  const action = known.action || "action";
  switch (known.state) {
    case "on_its_way":
      return `${action}: on its way to the habitat, answer expected at ${newsClock(known.expected_at)} UTC`;
    case "unknown":
      return known.final
        ? `${action}: outcome unknown: no answer from the habitat by ${newsClock(known.gives_up_at)} UTC (see the run's log)`
        : `${action}: outcome unknown: no answer by ${newsClock(known.expected_at)} UTC as expected; ` +
          `still listening until ${newsClock(known.gives_up_at)} UTC`;
    case "done":
      return `${action}: ${known.result || "done"}`;
    default:
      return `${action}: ${known.error || known.state}`;
  }
}

// Show an action the server said is on its way, and follow it until its answer (or none can come).
function followAction(runId, known) {
  const list = $("action-news");
  const item = element("li", "action-news");
  item.dataset.request = String(known.request);
  list.append(item);
  const show = (now) => {
    item.dataset.state = now.state;
    item.textContent = newsText(now);
  };
  show(known);
  const ask = async () => {
    if (view.runId !== runId || !item.isConnected) return;  // another run opened: its news is not this run's
    try {
      const now = await api("GET", `/api/runs/${encodeURIComponent(runId)}/actions/${known.request}`);
      show(now);
      if (now.final) return;
    } catch (error) {
      if (error.status === 404 || error.status === 401) return;
    }
    setTimeout(ask, NEWS_POLL_MS);
  };
  setTimeout(ask, NEWS_POLL_MS);
}

// Another run opened: the last one's actions are not shown with it.
function clearActionNews() {
  $("action-news").replaceChildren();
}
