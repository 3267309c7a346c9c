// Scene objects between the camera and what matters fade: the point it looks at, every template
// object and waypoint, and the robot's tool. So an operator sees the arm from outside a module's
// walls, the green filter inside the cabinet that holds it and the gripper reaching in for it,
// without a per-scene rule.
import * as THREE from 'three';

const FADED_OPACITY = 0.12;

export class Occluders {
  constructor() {
    this.meshes = [];
    this._box = new THREE.Box3();
    this._hit = new THREE.Vector3();
  }

  /** Watch every mesh under ``root`` (the scene's objects; never the robot or templates). */
  watch(root) {
    this.root = root;
    this.meshes = [];
    root.traverse((o) => {
      if (!o.isMesh) return;
      const m = o.material;
      o.userData.look = { opacity: m.opacity, transparent: m.transparent, depthWrite: m.depthWrite };
      this.meshes.push(o);
    });
  }

  /** Fade the meshes that the lines of sight from ``eye`` to any of ``targets`` cross before
   * reaching it (a mesh holding a target is not in its way). */
  update(eye, targets) {
    const rays = targets.map((t) => ({ target: t, distance: eye.distanceTo(t), ray: new THREE.Ray(eye.clone(), t.clone().sub(eye).normalize()) }));
    for (const mesh of this.meshes) {
      this._box.setFromObject(mesh);
      const fade = rays.some(({ target, distance, ray }) => {
        if (this._box.containsPoint(target)) return false;
        const hit = ray.intersectBox(this._box, this._hit);
        return hit !== null && eye.distanceTo(hit) < distance;
      });
      const m = mesh.material;
      const look = mesh.userData.look;
      m.opacity = fade ? Math.min(look.opacity, FADED_OPACITY) : look.opacity;
      m.transparent = fade || look.transparent;
      m.depthWrite = !fade && look.depthWrite;
      mesh.userData.faded = fade;
    }
  }

  /** The names of the watched objects (the children of the watched root) a faded mesh belongs to. */
  faded() {
    const names = new Set();
    for (const mesh of this.meshes) {
      if (!mesh.userData.faded) continue;
      let o = mesh;
      while (o.parent && o.parent !== this.root) o = o.parent;
      names.add(o.name);
    }
    return [...names].sort();
  }
}
