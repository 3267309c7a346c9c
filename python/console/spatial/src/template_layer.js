// Running Affordance Templates: display objects (translucent green) and end-effector waypoints
// (teal gripper marker with axes), each with its name. Entries are keyed by frame name
// (``cdra_filter:0``, ``0.2:cdra_filter:0``), unique across templates; an update repositions
// what it already has and builds only what is new.
import * as THREE from 'three';
import { label } from './labels.js';
import { placeAt, poseDifference } from './poses.js';
import { shapeObject } from './shapes.js';

export const WAYPOINT_COLOR = [0.0, 0.62, 0.62, 1.0];
const OBJECT_OPACITY = 0.45;

/** A gripper-like marker in a waypoint's frame: fingers along +z (approach) ending at the tool point. */
function waypointMarker(compact) {
  const group = new THREE.Group();
  const mat = new THREE.MeshLambertMaterial({ color: new THREE.Color(...WAYPOINT_COLOR.slice(0, 3)), transparent: true, opacity: 0.85 });
  if (compact) {
    group.add(new THREE.Mesh(new THREE.SphereGeometry(0.012, 12, 8), mat));
    return group;
  }
  const finger = new THREE.BoxGeometry(0.008, 0.008, 0.05);
  const palm = new THREE.BoxGeometry(0.012, 0.07, 0.012);
  const stem = new THREE.BoxGeometry(0.01, 0.01, 0.04);
  for (const [geometry, x, y, z] of [[finger, 0, 0.031, -0.025], [finger, 0, -0.031, -0.025], [palm, 0, 0, -0.056], [stem, 0, 0, -0.082]]) {
    const m = new THREE.Mesh(geometry, mat);
    m.position.set(x, y, z);
    group.add(m);
  }
  group.add(new THREE.AxesHelper(0.05));
  return group;
}

export class TemplateLayer {
  constructor({ loadMesh }) {
    this.group = new THREE.Group();
    this.group.name = 'templates';
    this.loadMesh = loadMesh;
    this.entries = new Map(); // id -> {id, kind, template, data, object, pose}
  }

  /** Replace the running templates with ``templates`` (the contract's list). */
  update(templates) {
    const seen = new Set();
    for (const t of templates) {
      for (const o of t.display_objects) seen.add(this._put(o.frame, 'display_object', t, o));
      for (const w of t.waypoints) seen.add(this._put(w.name, 'waypoint', t, w));
    }
    for (const [id, entry] of this.entries) {
      if (!seen.has(id)) {
        this.group.remove(entry.object);
        this.entries.delete(id);
      }
    }
  }

  _put(id, kind, template, data) {
    let entry = this.entries.get(id);
    const look = JSON.stringify(kind === 'waypoint' ? { compact: !!data.compact } : data.shape);
    if (!entry || entry.look !== look) {
      if (entry) this.group.remove(entry.object);
      const object = new THREE.Group();
      object.name = id;
      object.userData.spatialId = id;
      if (kind === 'waypoint') {
        object.add(waypointMarker(!!data.compact));
      } else {
        object.add(shapeObject(data.shape, { opacity: OBJECT_OPACITY, loadMesh: this.loadMesh }));
      }
      object.add(label(id, kind));
      this.group.add(object);
      entry = { id, kind, object, look };
      this.entries.set(id, entry);
    }
    entry.template = template;
    entry.data = data;
    entry.pose = data.pose;
    placeAt(entry.object, data.pose);
    return id;
  }

  get(id) { return this.entries.get(id); }

  /** The entry an Object3D belongs to, if any (for picking). */
  entryOf(object) {
    for (let o = object; o; o = o.parent) if (o.userData.spatialId) return this.entries.get(o.userData.spatialId);
    return undefined;
  }

  /** Whether entry ``id`` now sits at ``pose`` (1 mm, 0.01 rad). */
  at(id, pose) {
    const entry = this.entries.get(id);
    if (!entry) return false;
    const d = poseDifference(entry.pose, pose);
    return d.distance <= 1e-3 && d.angle <= 1e-2;
  }

  /** What tests and the page may read: every entry's name, kind and pose. */
  describe() {
    const out = {};
    for (const [id, e] of this.entries) out[id] = { kind: e.kind, template: e.template.key, pose: e.pose };
    return out;
  }
}
