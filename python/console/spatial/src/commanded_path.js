// The motion the arm has been told to follow, drawn ahead of it. On a 1.3 s link the arm drawn is
// where the habitat last reported it, a light time ago or more; while a plan executes (the feed
// sends it with ``commanded: true``) this line through the tool's positions along the plan shows
// where it is going, ending in a ring at the commanded end. The ring turns solid only once a
// reported state has the tool there: nothing is shown as reached before telemetry says so.
import * as THREE from 'three';

const LINE = new THREE.LineDashedMaterial({ color: 0xffb347, dashSize: 0.03, gapSize: 0.02, depthTest: false, transparent: true });
const OPEN_END = new THREE.MeshBasicMaterial({ color: 0xffb347, wireframe: true, depthTest: false, transparent: true });
const REACHED_END = new THREE.MeshBasicMaterial({ color: 0xffb347, depthTest: false, transparent: true });
/** How near (m) a reported tool position must be to the commanded end to count as there. */
export const REACHED_M = 0.01;
const MAX_SAMPLES = 120; // tool positions along the path: enough for a smooth line, cheap to compute

export class CommandedPath {
  constructor() {
    this.object = new THREE.Group();
    this.object.name = 'commanded path';
    this.object.renderOrder = 2; // over the scene: a path inside a cabinet is still seen
    this.plan = null;
    this.end = null;
    this.reached = false;
  }

  /** Draw ``plan``'s tool path, computed with ``model`` (a RobotModel moved through the plan's
   * points from ``baseline``); ``model`` is left at the plan's end. */
  set(plan, model, baseline) {
    this.clear();
    const points = plan.points;
    const step = Math.max(1, Math.ceil(points.length / MAX_SAMPLES));
    const along = [];
    for (let i = 0; i < points.length; i += step) along.push(this._toolAt(plan, points[i], model, baseline));
    if ((points.length - 1) % step !== 0) along.push(this._toolAt(plan, points[points.length - 1], model, baseline));
    const line = new THREE.Line(new THREE.BufferGeometry().setFromPoints(along), LINE);
    line.computeLineDistances();
    line.renderOrder = 2;
    this.end = along[along.length - 1].clone();
    this.ring = new THREE.Mesh(new THREE.TorusGeometry(0.03, 0.006, 8, 24), OPEN_END);
    this.ring.position.copy(this.end);
    this.ring.renderOrder = 2;
    this.object.add(line, this.ring);
    this.plan = plan;
    this.reached = false;
  }

  clear() {
    for (const child of [...this.object.children]) {
      child.geometry.dispose();
      this.object.remove(child);
    }
    this.plan = null;
    this.end = null;
    this.reached = false;
  }

  /** The tool where the habitat last reported it (world xyz): the end counts as reached once it is there. */
  reported(toolXyz) {
    if (!this.end || this.reached) return false;
    if (this.end.distanceTo(new THREE.Vector3(...toolXyz)) > REACHED_M) return false;
    this.reached = true;
    this.ring.material = REACHED_END;
    return true;
  }

  describe() {
    if (!this.plan) return { visible: false };
    return { visible: true, instance: this.plan.instance, trajectory: this.plan.trajectory, end: this.end.toArray(), reached: this.reached };
  }

  _toolAt(plan, point, model, baseline) {
    const positions = { ...baseline };
    plan.joint_names.forEach((name, j) => { positions[name] = point.positions[j]; });
    model.setJoints(positions);
    model.object.updateMatrixWorld(true);
    return new THREE.Vector3(...model.toolPose().xyz);
  }
}
