// Drives roslibjs (npm `roslib`) through the `clients` cases of `caretaker interop --serve`.
// Usage: node roslibjs_driver.js ws://HOST:PORT NODE_MODULES_DIR
// One roslibjs Ros per case on the case's path, used as a program would use it, and one more on
// /report that tells the server what the program received. The waits are the driver's patience
// with the client (how long a program would wait before calling it a failure); the server's
// answers to the reports say when a step has been played.
"use strict";

const fs = require("node:fs");
const path = require("node:path");
const { pathToFileURL } = require("node:url");

const PATIENCE_MS = 3000;

/** roslib is an ES module with an `import` export only: load its entry from the given node_modules. */
async function loadRoslib(modules) {
  const dir = path.join(modules, "roslib");
  const pkg = JSON.parse(fs.readFileSync(path.join(dir, "package.json"), "utf8"));
  const entry = (pkg.exports && pkg.exports["."] && pkg.exports["."].import) || pkg.module || pkg.main;
  return import(pathToFileURL(path.join(dir, entry)).href);
}

/** Resolves with what `executor` hands over, or with `undefined` once the patience has run out. */
function within(ms, executor) {
  return new Promise((resolve) => {
    const timer = setTimeout(() => resolve(undefined), ms);
    executor((value) => { clearTimeout(timer); resolve(value); });
  });
}

async function main() {
  const [url, modules] = process.argv.slice(2);
  if (!url || !/^wss?:\/\//.test(url) || !modules) {
    console.error("usage: node roslibjs_driver.js ws://HOST:PORT NODE_MODULES_DIR");
    return 2;
  }
  const base = url.replace(/\/+$/, "");
  const { Ros, Service, Topic } = await loadRoslib(modules);
  const pkg = JSON.parse(fs.readFileSync(path.join(modules, "roslib", "package.json"), "utf8"));

  async function open(pathName, beforeConnect) {
    const ros = new Ros({});
    if (beforeConnect) beforeConnect(ros);
    const opened = new Promise((resolve, reject) => {
      ros.once("connection", resolve);
      ros.once("error", reject);
    });
    await ros.connect(`${base}/${pathName}`);
    await opened;
    return ros;
  }

  const reporter = await open("report");
  const reportService = new Service({ ros: reporter, name: "/interop/report", serviceType: "interop/Report" });
  function report(caseId, observed) {
    console.log(`${caseId}: ${JSON.stringify(observed).slice(0, 200)}`);
    return new Promise((resolve, reject) => {
      reportService.callService({ case: caseId, observed: JSON.stringify(observed) }, resolve, reject);
    });
  }

  async function outOfOrder() {
    const ros = await open("clients.1");
    const echo = new Service({ ros, name: "/interop/echo", serviceType: "interop/Echo" });
    const got = {};
    await within(2 * PATIENCE_MS, (done) => {
      for (const name of ["first", "second"]) {
        const keep = (values) => {
          got[name] = values && typeof values === "object" ? values.data : values;
          if (Object.keys(got).length === 2) done();
        };
        echo.callService({ data: name }, keep, keep);
      }
    });
    await report("clients.1", { ...got, done: true });
    ros.close();
  }

  async function messages(caseId, topicName) {
    const ros = await open(caseId);
    const observed = { received: [], status: null };
    ros.on("status", (status) => { observed.status = status.msg; });
    await within(PATIENCE_MS, (done) => {
      new Topic({ ros, name: topicName, messageType: "std_msgs/msg/String" }).subscribe((message) => {
        observed.received.push(message.data);
        if (message.data === "after") done();
      });
    });
    await report(caseId, { ...observed, done: true });
    ros.close();
  }

  async function dropped() {
    const ros = await open("clients.4");
    const received = [];
    let arrived;
    const reconnected = new Promise((resolve) => { arrived = resolve; });
    new Topic({ ros, name: "/interop/drop", messageType: "std_msgs/msg/String" }).subscribe((message) => {
      received.push(message.data);
      if (message.data === "after-reconnect") arrived();
    });
    new Topic({ ros, name: "/interop/drop_pub", messageType: "std_msgs/msg/String" }).advertise();
    await new Service({ ros, name: "/interop/drop_service", serviceType: "std_srvs/srv/Trigger" })
      .advertise((request, response) => { response.success = true; return true; });
    const registered = ["subscribe /interop/drop", "advertise /interop/drop_pub",
      "advertise_service /interop/drop_service"];
    const answer = await report("clients.4", { registered });
    if (answer && answer.reconnected) await within(PATIENCE_MS, (done) => reconnected.then(done));
    await report("clients.4", { received, done: true });
    ros.close();
  }

  async function slow() {
    const ros = await open("clients.5");
    let late;
    const lateAnswer = new Promise((resolve) => { late = resolve; });
    // roslibjs's timeout (seconds) goes to the server in the call; the client keeps no timer of its own
    new Service({ ros, name: "/interop/slow", serviceType: "interop/Echo" }).callService(
      {}, (values) => late(`answered ${JSON.stringify(values)}`), (error) => late(`failed: ${error}`), 0.5);
    const outcome = await within(4 * 500, (done) => lateAnswer.then(done));
    await report("clients.5", { timeout_offered: true, slow_call: outcome ?? "no answer within 2 s" });
    await within(PATIENCE_MS, (done) => lateAnswer.then(done));
    const after = await within(PATIENCE_MS, (done) => {
      new Service({ ros, name: "/interop/echo", serviceType: "interop/Echo" }).callService(
        { data: "after-late" }, (values) => done(values.data), (error) => done(`error: ${error}`));
    });
    await report("clients.5", { after_late: after ?? "no answer", done: true });
    ros.close();
  }

  async function refusedAuth() {
    const observed = { auth_offered: true, refusal: null, closed: false };
    const ros = await open("clients.6", (r) => {
      r.on("status", (status) => { observed.refusal = observed.refusal ?? `status: ${status.msg}`; });
    });
    const closed = within(PATIENCE_MS, (done) => ros.on("close", (event) => {
      observed.closed = true;
      if (event && event.code === 1008 && event.reason) observed.refusal = observed.refusal ?? `close 1008: ${event.reason}`;
      done();
    }));
    const now = Date.now() / 1000;
    ros.authenticate("0".repeat(64), "interop", `${base}/clients.6`, "0123456789abcdef", now, "user", now + 60);
    await closed;
    await report("clients.6", { ...observed, connected: ros.isConnected, done: true });
    ros.close();
  }

  await report("hello", { client: `roslibjs ${pkg.version}` });
  await outOfOrder();
  await messages("clients.2", "/interop/fragmented");
  await messages("clients.3", "/interop/status_after");
  await dropped();
  await slow();
  await refusedAuth();
  await report("bye", {});
  reporter.close();
  return 0;
}

main().then((code) => process.exit(code), (error) => { console.error(error); process.exit(1); });
