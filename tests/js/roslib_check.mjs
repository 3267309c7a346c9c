// roslibjs (npm roslib) against a running Caretaker rosbridge server and the test peer node.
// Usage: node roslib_check.mjs ws://127.0.0.1:PORT
// Prints one JSON line per check ({"check": name, "ok": bool, ...}) and exits 1 if any failed.
import { Action, Ros, Service, Topic } from "roslib";

const url = process.argv[2];
const results = [];
const TIMEOUT_MS = 20000;

function withTimeout(name, executor) {
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${name}: no answer within ${TIMEOUT_MS} ms`)), TIMEOUT_MS);
    executor((value) => { clearTimeout(timer); resolve(value); }, (error) => { clearTimeout(timer); reject(error); });
  });
}

async function check(name, body) {
  try {
    const detail = await body();
    results.push({ check: name, ok: true, detail });
  } catch (error) {
    results.push({ check: name, ok: false, error: String(error && error.message ? error.message : error) });
  }
  console.log(JSON.stringify(results[results.length - 1]));
}

const ros = new Ros({ url });
await check("connect", () => withTimeout("connect", (resolve, reject) => {
  ros.on("connection", () => resolve(url));
  ros.on("error", reject);
}));

await check("getTopics", () => withTimeout("getTopics", (resolve, reject) => {
  ros.getTopics((result) => result.topics.includes("/peer/echo_out")
    ? resolve(result.topics.length) : reject(new Error(`no /peer/echo_out in ${result.topics}`)), reject);
}));

await check("pubsub", () => withTimeout("pubsub", (resolve) => {
  const listener = new Topic({ ros, name: "/peer/echo_out", messageType: "std_msgs/String" });
  const talker = new Topic({ ros, name: "/peer/echo_in", messageType: "std_msgs/msg/String" });
  // ROS matches the new publisher asynchronously: publish until the first echo comes back.
  const sender = setInterval(() => talker.publish({ data: "from roslibjs" }), 100);
  listener.subscribe((message) => {
    if (message.data === "from roslibjs") {
      clearInterval(sender);
      listener.unsubscribe();
      resolve(message.data);
    }
  });
}));

await check("callService", () => withTimeout("callService", (resolve, reject) => {
  new Service({ ros, name: "/peer/set_bool", serviceType: "std_srvs/SetBool" })
    .callService({ data: true }, (response) => response.success && response.message === "got true"
      ? resolve(response) : reject(new Error(JSON.stringify(response))), reject);
}));

await check("failedServiceCall", () => withTimeout("failedServiceCall", (resolve, reject) => {
  new Service({ ros, name: "/no/such/service", serviceType: "std_srvs/Trigger" })
    .callService({}, (response) => reject(new Error(`unexpected success ${JSON.stringify(response)}`)),
      (error) => String(error).includes("Service /no/such/service does not exist")
        ? resolve(String(error)) : reject(new Error(`wrong error ${error}`)));
}));

for (const compression of ["png", "cbor"]) {
  await check(`subscribe ${compression}`, () => withTimeout(compression, (resolve, reject) => {
    const topic = new Topic({ ros, name: "/peer/latched", messageType: "std_msgs/String", compression });
    topic.subscribe((message) => {
      topic.unsubscribe();
      message.data === "latched value" ? resolve(message) : reject(new Error(JSON.stringify(message)));
    });
  }));
}

await check("advertiseService", async () => {
  const provided = new Service({ ros, name: "/js/provided", serviceType: "std_srvs/SetBool" });
  await provided.advertise((request, response) => {
    response.success = !request.data;
    response.message = "served by roslibjs";
    return true;
  });
  const caller = new Service({ ros, name: "/js/provided", serviceType: "std_srvs/SetBool" });
  for (let attempt = 0; attempt < 50; attempt++) {  // the service appears on the ROS graph asynchronously
    try {
      const response = await withTimeout("provided call", (resolve, reject) =>
        caller.callService({ data: true }, resolve, reject));
      if (response.message !== "served by roslibjs" || response.success !== false) {
        throw new Error(JSON.stringify(response));
      }
      await provided.unadvertise();
      return response;
    } catch (error) {
      if (!String(error).includes("does not exist") && !String(error).includes("no server")) throw error;
      await new Promise((resolve) => setTimeout(resolve, 100));  // retry after discovery
    }
  }
  throw new Error("the advertised service never answered");
});

await check("sendGoal", () => withTimeout("sendGoal", (resolve, reject) => {
  const action = new Action({ ros, name: "/peer/follow", actionType: "caretaker_sim_msgs/action/FollowJointTrajectory" });
  const feedback = [];
  action.sendGoal({ trajectory: { joint_names: ["a"], points: [{ positions: [1.0] }, { positions: [2.0] }] },
    goal_tolerance: 0.1 },
  (result) => result.error_string === "followed 2 points" ? resolve({ result, feedback: feedback.length })
    : reject(new Error(JSON.stringify(result))),
  (fb) => feedback.push(fb), reject);
}));

ros.close();
process.exit(results.every((result) => result.ok) ? 0 : 1);
