// The 3D view of a live run beside the procedure (spatial/README.md): the robot, the scene,
// the running templates, the ghost plan, the robot camera, registration by dragging.
// Loaded after app.js (its `view`, `$`, `api`); app.js calls spatialPanel.open/close.
//
// Data comes only from this server's /ws/runs/ID/spatial (the ground feed over the robot's
// rosbridge link); a drag is POSTed to /api/runs/ID/spatial/pose, which sends it through PAX
// as the signed-in operator (observers get 403; the view gives them no handles either).
"use strict";

const spatialPanel = (() => {
  const state = { runId: null, socket: null, view: null, timer: null, clearing: null };
  // A command's success is news for a moment, not for the rest of the run; errors stay until the next message.
  const SUCCESS_SHOWN_MS = 6000;

  function status(text, tone = "", { clears = false } = {}) {
    const node = $("spatial-status");
    clearTimeout(state.clearing);
    node.textContent = text;
    node.dataset.tone = tone;
    if (clears) state.clearing = setTimeout(() => { if (node.textContent === text) status(""); }, SUCCESS_SHOWN_MS);
  }

  function ensureView() {
    if (state.view) return state.view;
    const mayAct = Boolean(view.me && view.me.may_act);
    state.view = new CaretakerSpatial.SpatialView($("spatial-view"), {
      canAct: mayAct,
      onPoseCommand: (command) => send(command),
      onError: (message) => status(message, "error"),
      // the arm's age on the ground server's clock, as the countdowns use it
      clock: () => Date.now() + view.clockOffset,
    });
    return state.view;
  }

  async function send(command) {
    const runId = state.runId;
    status(`sending ${command.command} for ${command.target}…`);
    try {
      const answer = await api("POST", `/api/runs/${encodeURIComponent(runId)}/spatial/pose`,
                               {command: command.command, args: command.args});
      if (state.runId !== runId || !state.view) return;
      state.view.resolvePending(command.target, answer.outcome);
      const succeeded = answer.outcome === "succeeded";
      status(`${command.command} ${answer.outcome}${answer.message ? ": " + answer.message : ""}`,
             succeeded ? "" : "error", { clears: succeeded });
    } catch (error) {
      if (state.runId !== runId || !state.view) return;
      state.view.resolvePending(command.target, "failed");
      status(`${command.command} refused: ${error.message}`, "error");
    }
  }

  function connect() {
    const runId = state.runId;
    const scheme = location.protocol === "https:" ? "wss" : "ws";
    const socket = new WebSocket(`${scheme}://${location.host}/ws/runs/${encodeURIComponent(runId)}/spatial`);
    state.socket = socket;
    status("waiting for the robot's description over the link…");
    socket.addEventListener("message", (message) => {
      if (state.socket !== socket) return;
      const data = JSON.parse(message.data);
      if (data.type === "none") { $("spatial-panel").hidden = true; return; }
      if (data.type === "scene") {
        $("spatial-panel").hidden = false;  // shown once the robot's link gave a scene: no empty panel beside a run without one
        try { ensureView().load(data.document); status(""); } catch (error) { status(error.message, "error"); }
      } else if (data.type === "update") {
        const update = data.update;
        if (update.kind === "link") status(update.state === "connected" ? "" : `robot link: ${update.state} ${update.message}`,
                                           update.state === "error" ? "error" : "");
        else if (state.view) state.view.apply(update);
      }
    });
    socket.addEventListener("close", (event) => {
      if (state.socket !== socket) return;
      state.socket = null;
      if (event.code === 1000 || event.code === 1008) return;  // the run ended, or not allowed: app.js reopens the run
      status("3D feed lost; reconnecting…", "error");
      state.timer = setTimeout(() => { if (state.runId === runId) connect(); }, 2000);
    });
  }

  function close() {
    clearTimeout(state.timer);
    clearTimeout(state.clearing);
    const socket = state.socket;
    state.socket = null;
    if (socket) socket.close();
    if (state.view) state.view.dispose();
    state.view = null;
    state.runId = null;
    $("spatial-panel").hidden = true;
  }

  function open(runId, live) {
    if (live && state.runId === runId) return;  // the run's page reconnected: this feed reconnects by itself
    close();
    if (!live || typeof CaretakerSpatial === "undefined") return;
    state.runId = runId;
    connect();
  }

  return { open, close };
})();
