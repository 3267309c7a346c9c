// Scene objects between the camera and what matters fade: the point it looks at and every
// template object and waypoint. So an operator sees the arm from outside a module's walls and the
// green filter inside the cabinet that holds it, without a per-scene rule.
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

  faded() { return this.meshes.filter((m) => m.userData.faded).length; }
}
