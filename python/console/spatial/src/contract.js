// The data contract (README.md): checks that a scene document or an update has the shape the
// view relies on, so a malformed one is refused whole with the path of the bad value, and the
// view keeps showing what it had.

export const CONTRACT_VERSION = 1;

export class ContractError extends Error {
  constructor(where, message) {
    super(`${where}: ${message}`);
    this.name = 'ContractError';
    this.where = where;
  }
}

function fail(where, message) { throw new ContractError(where, message); }

const isObject = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);

function object(v, where) { if (!isObject(v)) fail(where, `expected an object, got ${JSON.stringify(v)}`); return v; }
function list(v, where) { if (!Array.isArray(v)) fail(where, `expected a list, got ${JSON.stringify(v)}`); return v; }
function string(v, where) { if (typeof v !== 'string' || !v) fail(where, `expected a non-empty string, got ${JSON.stringify(v)}`); return v; }
function number(v, where) { if (typeof v !== 'number' || !Number.isFinite(v)) fail(where, `expected a finite number, got ${JSON.stringify(v)}`); return v; }
function numbers(v, n, where) {
  list(v, where);
  if (v.length !== n) fail(where, `expected ${n} numbers, got ${v.length}`);
  v.forEach((x, i) => number(x, `${where}[${i}]`));
  return v;
}

export function checkPose(p, where) {
  object(p, where);
  numbers(p.xyz, 3, `${where}.xyz`);
  numbers(p.quat, 4, `${where}.quat`);
  if (Math.hypot(...p.quat) < 1e-9) fail(`${where}.quat`, 'the quaternion is zero');
  return p;
}

function checkShape(s, where) {
  object(s, where);
  if (s.pose !== undefined) checkPose(s.pose, `${where}.pose`);
  if (s.rgba !== undefined) numbers(s.rgba, 4, `${where}.rgba`);
  switch (s.type) {
    case 'box': case 'sphere': numbers(s.size, 3, `${where}.size`); break;
    case 'cylinder':
      if (s.size !== undefined) numbers(s.size, 3, `${where}.size`);
      else { number(s.radius, `${where}.radius`); number(s.length, `${where}.length`); }
      break;
    case 'mesh': string(s.mesh, `${where}.mesh`); if (s.size !== undefined) numbers(s.size, 3, `${where}.size`); break;
    default: fail(`${where}.type`, `unknown shape type ${JSON.stringify(s.type)}; expected box, cylinder, sphere or mesh`);
  }
}

function checkJoints(j, where) {
  object(j, where);
  object(j.positions, `${where}.positions`);
  for (const [name, value] of Object.entries(j.positions)) number(value, `${where}.positions.${name}`);
  if (j.stamp !== undefined) number(j.stamp, `${where}.stamp`);
}

function checkObjects(objects, where) {
  list(objects, where).forEach((o, i) => {
    const w = `${where}[${i}]`;
    object(o, w);
    string(o.name, `${w}.name`);
    checkPose(o.pose, `${w}.pose`);
    list(o.shapes, `${w}.shapes`).forEach((s, k) => checkShape(s, `${w}.shapes[${k}]`));
  });
}

export function checkTemplates(templates, where) {
  list(templates, where).forEach((t, i) => {
    const w = `${where}[${i}]`;
    object(t, w);
    string(t.key, `${w}.key`);
    string(t.type, `${w}.type`);
    number(t.id, `${w}.id`);
    list(t.display_objects, `${w}.display_objects`).forEach((o, k) => {
      const wo = `${w}.display_objects[${k}]`;
      object(o, wo);
      string(o.name, `${wo}.name`);
      string(o.frame, `${wo}.frame`);
      checkPose(o.pose, `${wo}.pose`);
      checkShape(o.shape, `${wo}.shape`);
      object(o.parent_frame, `${wo}.parent_frame`);
      string(o.parent_frame.name, `${wo}.parent_frame.name`);
      if (o.parent_frame.pose !== null) checkPose(o.parent_frame.pose, `${wo}.parent_frame.pose`);
    });
    list(t.waypoints, `${w}.waypoints`).forEach((p, k) => {
      const wp = `${w}.waypoints[${k}]`;
      object(p, wp);
      string(p.name, `${wp}.name`);
      string(p.trajectory, `${wp}.trajectory`);
      number(p.index, `${wp}.index`);
      checkPose(p.pose, `${wp}.pose`);
    });
  });
}

export function checkPlan(plan, where) {
  if (plan === null) return;
  object(plan, where);
  string(plan.instance, `${where}.instance`);
  string(plan.trajectory, `${where}.trajectory`);
  const names = list(plan.joint_names, `${where}.joint_names`);
  names.forEach((n, i) => string(n, `${where}.joint_names[${i}]`));
  const points = list(plan.points, `${where}.points`);
  if (points.length === 0) fail(`${where}.points`, 'a plan needs at least its start point');
  let previous = -Infinity;
  points.forEach((p, i) => {
    object(p, `${where}.points[${i}]`);
    numbers(p.positions, names.length, `${where}.points[${i}].positions`);
    const t = number(p.time_from_start, `${where}.points[${i}].time_from_start`);
    if (t < previous) fail(`${where}.points[${i}].time_from_start`, `time ${t} goes back (previous ${previous})`);
    previous = t;
  });
  list(plan.waypoints, `${where}.waypoints`).forEach((w, i) => {
    object(w, `${where}.waypoints[${i}]`);
    string(w.name, `${where}.waypoints[${i}].name`);
    const k = number(w.point, `${where}.waypoints[${i}].point`);
    if (!Number.isInteger(k) || k < 0 || k >= points.length) fail(`${where}.waypoints[${i}].point`, `expected a point index 0..${points.length - 1}, got ${k}`);
  });
  if (plan.end_pose !== null && plan.end_pose !== undefined) checkPose(plan.end_pose, `${where}.end_pose`);
  if (plan.commanded !== undefined && typeof plan.commanded !== 'boolean') {
    fail(`${where}.commanded`, `expected true or false, got ${JSON.stringify(plan.commanded)}`);
  }
}

export function checkScene(doc) {
  object(doc, 'scene');
  if (doc.contract !== CONTRACT_VERSION) fail('scene.contract', `this view reads contract ${CONTRACT_VERSION}, got ${JSON.stringify(doc.contract)}`);
  if (doc.kind !== 'scene') fail('scene.kind', `expected "scene", got ${JSON.stringify(doc.kind)}`);
  string(doc.frame, 'scene.frame');
  const r = object(doc.robot, 'scene.robot');
  string(r.name, 'scene.robot.name');
  string(r.urdf, 'scene.robot.urdf');
  string(r.tool_link, 'scene.robot.tool_link');
  checkPose(r.base_pose, 'scene.robot.base_pose');
  list(r.arm_joints, 'scene.robot.arm_joints').forEach((n, i) => string(n, `scene.robot.arm_joints[${i}]`));
  if (r.mesh_urls !== undefined) object(r.mesh_urls, 'scene.robot.mesh_urls');
  if (r.end_effector_poses !== undefined) object(r.end_effector_poses, 'scene.robot.end_effector_poses');
  checkJoints(doc.joints, 'scene.joints');
  checkObjects(doc.objects, 'scene.objects');
  checkTemplates(doc.templates, 'scene.templates');
  checkPlan(doc.plan, 'scene.plan');
  if (doc.camera !== undefined && doc.camera !== null) object(doc.camera, 'scene.camera');
  if (doc.viewpoint !== undefined && doc.viewpoint !== null) {
    object(doc.viewpoint, 'scene.viewpoint');
    numbers(doc.viewpoint.eye, 3, 'scene.viewpoint.eye');
    numbers(doc.viewpoint.target, 3, 'scene.viewpoint.target');
    if (doc.viewpoint.fov_deg !== undefined) number(doc.viewpoint.fov_deg, 'scene.viewpoint.fov_deg');
  }
  return doc;
}

function checkLocated(l, where) {
  object(l, where);
  string(l.object, `${where}.object`);
  string(l.camera, `${where}.camera`);
  if (typeof l.message !== 'string') fail(`${where}.message`, `expected a string, got ${JSON.stringify(l.message)}`);
  if (typeof l.success !== 'boolean') fail(`${where}.success`, `expected true or false, got ${JSON.stringify(l.success)}`);
  if (l.success) checkPose(l.pose, `${where}.pose`);
  for (const k of ['residual_px', 'offset_mm', 'offset_deg']) number(l[k], `${where}.${k}`);
  list(l.markers, `${where}.markers`).forEach((m, i) => number(m, `${where}.markers[${i}]`));
}

export function checkUpdate(u) {
  object(u, 'update');
  switch (u.kind) {
    case 'joints': checkJoints(u, 'update'); break;
    case 'objects':
      object(u.poses, 'update.poses');
      for (const [name, p] of Object.entries(u.poses)) checkPose(p, `update.poses.${name}`);
      break;
    case 'templates': checkTemplates(u.templates, 'update.templates'); break;
    case 'plan': checkPlan(u.plan, 'update.plan'); break;
    case 'camera': if (u.url !== null) string(u.url, 'update.url'); break;
    case 'located': checkLocated(u.located, 'update.located'); break;
    default: fail('update.kind', `unknown update ${JSON.stringify(u.kind)}; expected joints, objects, templates, plan, camera or located`);
  }
  return u;
}
