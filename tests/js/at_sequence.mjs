// The AT service sequence of tests/interop/test_clients_agree.py, from roslibjs (npm roslib).
// Usage: node at_sequence.mjs ws://127.0.0.1:PORT
// Prints one JSON object: what each step answered.
import { Ros, Service } from "roslib";

const url = process.argv[2];
const TIMEOUT_MS = 60000;
const ros = new Ros({ url });

function call(name, type, request) {
  return new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error(`${name}: no answer within ${TIMEOUT_MS} ms`)), TIMEOUT_MS);
    new Service({ ros, name: `/affordance_template_server/${name}`, serviceType: `affordance_template_msgs/srv/${type}` })
      .callService(request, (response) => { clearTimeout(timer); resolve(response); },
        (error) => { clearTimeout(timer); reject(new Error(`${name}: ${error}`)); });
  });
}

await new Promise((resolve, reject) => { ros.on("connection", resolve); ros.on("error", reject); });
const added = await call("add_template", "AddAffordanceTemplate", { class_type: "cdra_filter", hide_waypoints: false });
const registered = await call("set_object_pose", "SetObjectPose", {
  objects: [{ type: "cdra_filter", name: "cdra_filter", id: added.id,
              stamped_pose: { header: { frame_id: "cabinet/slot" }, pose: { orientation: { w: 1.0 } } } }],
});
const planned = await call("plan_command", "AffordanceTemplatePlanCommand",
  { type: "cdra_filter", id: added.id, trajectory_name: "grasp_and_pull" });
const wrong = await call("plan_command", "AffordanceTemplatePlanCommand",
  { type: "cdra_filter", id: added.id, trajectory_name: "no_such_trajectory" });
const running = await call("get_running", "GetRunningAffordanceTemplates", {});
const deleted = await call("delete_template", "DeleteAffordanceTemplate", { class_type: "cdra_filter", id: added.id });
console.log(JSON.stringify({
  instance: added.instance, added: added.success, registered: registered.success,
  planned: planned.success, plan_valid: planned.affordance_template_status.plan_valid,
  unknown_trajectory_refused: !wrong.success, unknown_trajectory_message: wrong.message,
  running_after_add: running.templates.includes(added.instance), deleted: deleted.success,
}));
ros.close();
