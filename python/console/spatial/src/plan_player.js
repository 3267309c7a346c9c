// The planned motion as a ghost arm: a second, translucent robot that plays, scrubs and steps
// through the plan's joint path before the operator presses Execute.
import * as THREE from 'three';
import { RobotModel } from './robot_model.js';

const GHOST = new THREE.MeshLambertMaterial({ color: 0xffb347, transparent: true, opacity: 0.4, depthWrite: false });

export class PlanPlayer {
  constructor(robot, { onError, onChange }) {
    this.robot = robot;
    this.ghost = new RobotModel(robot, { material: GHOST, onError, onMeshLoaded: () => onChange?.() });
    this.ghost.object.visible = false;
    this.object = this.ghost.object;
    this.onChange = onChange;
    this.plan = null;
    this.time = 0;
    this.playing = false;
  }

  get duration() { return this.plan ? this.plan.points[this.plan.points.length - 1].time_from_start : 0; }

  /** Show ``plan`` (null removes the ghost); ``baseline`` fills the joints the plan does not move. */
  setPlan(plan, baseline) {
    this.plan = plan;
    this.playing = false;
    this.ghost.object.visible = !!plan;
    if (plan) {
      this.ghost.setJoints(baseline);
      this.baseline = { ...baseline };
      this.seek(this.duration);
    }
    this.onChange();
  }

  play() {
    if (!this.plan) return;
    if (this.time >= this.duration) this.time = 0;
    this.playing = true;
    this.onChange();
  }

  pause() { this.playing = false; this.onChange(); }

  /** Advance playback by ``dt`` seconds of plan time. */
  tick(dt) {
    if (!this.playing) return;
    const t = Math.min(this.duration, this.time + dt);
    if (t >= this.duration) this.playing = false;
    this.seek(t);
  }

  /** Put the ghost where the plan has the arm at time ``t`` (clamped to the plan). */
  seek(t) {
    if (!this.plan) return;
    const points = this.plan.points;
    this.time = Math.max(0, Math.min(this.duration, t));
    let i = 0;
    while (i < points.length - 1 && points[i + 1].time_from_start <= this.time) i += 1;
    const a = points[i];
    const b = points[Math.min(i + 1, points.length - 1)];
    const span = b.time_from_start - a.time_from_start;
    const f = span > 0 ? (this.time - a.time_from_start) / span : 0;
    const positions = {};
    this.plan.joint_names.forEach((name, j) => { positions[name] = a.positions[j] + f * (b.positions[j] - a.positions[j]); });
    this.point = i + f;
    this.ghost.setJoints({ ...this.gripperAt(i), ...positions });
    this.onChange();
  }

  /** End-effector joints of the last waypoint reached by point ``i`` (the gripper acts after the arm). */
  gripperAt(i) {
    const poses = this.robot.end_effector_poses || {};
    let joints = {};
    for (const name of Object.keys(poses)) for (const j of Object.keys(poses[name])) if (j in this.baseline) joints[j] = this.baseline[j];
    for (const w of this.plan.waypoints) if (w.point <= i && poses[w.end_effector_pose]) joints = { ...joints, ...poses[w.end_effector_pose] };
    return joints;
  }

  seekPoint(k) {
    if (!this.plan) return;
    const points = this.plan.points;
    this.seek(points[Math.max(0, Math.min(points.length - 1, k))].time_from_start);
  }

  /** Pause at the next (``+1``) or previous (``-1``) waypoint; the start counts as the first stop back. */
  stepWaypoint(direction) {
    if (!this.plan) return;
    this.playing = false;
    const eps = 1e-6;
    const times = [0, ...this.plan.waypoints.map((w) => this.plan.points[w.point].time_from_start)].sort((x, y) => x - y);
    const target = direction > 0 ? times.find((t) => t > this.time + eps) : [...times].reverse().find((t) => t < this.time - eps);
    this.seek(target ?? (direction > 0 ? this.duration : 0));
  }

  /** The waypoint the ghost is at or has last passed. */
  currentWaypoint() {
    if (!this.plan) return null;
    let current = null;
    for (const w of this.plan.waypoints) if (this.plan.points[w.point].time_from_start <= this.time + 1e-6) current = w;
    return current;
  }

  describe() {
    if (!this.plan) return { visible: false };
    const w = this.currentWaypoint();
    return {
      visible: this.ghost.object.visible,
      instance: this.plan.instance,
      trajectory: this.plan.trajectory,
      playing: this.playing,
      time: this.time,
      duration: this.duration,
      point: this.point,
      waypoint: w ? w.name : null,
      joints: { ...this.ghost.positions },
      tool_pose: this.ghost.toolPose(),
      links: this.ghost.linkPoses(),
    };
  }
}
