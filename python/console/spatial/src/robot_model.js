// A robot from its URDF text (urdf-loader), placed at its base pose, moved by joint values.
// Meshes are fetched only through the document's URL map: the view never guesses a URL.
import * as THREE from 'three';
import URDFLoader from 'urdf-loader';
import { placeAt, worldPose } from './poses.js';

export class RobotModel {
  /**
   * @param robot the scene document's ``robot``
   * @param {{material?: THREE.Material, onError: (message: string) => void, onMeshLoaded?: () => void}} options
   *   ``material`` replaces every link's material (the ghost arm); ``onMeshLoaded`` hears each
   *   mesh that arrived (a view drawing on demand draws it then, and need not poll for it).
   */
  constructor(robot, { material, onError, onMeshLoaded }) {
    const loader = new URDFLoader();
    const meshUrls = robot.mesh_urls || {};
    // Keep package:// URIs as they are, so the URL map is keyed by what the URDF says.
    loader.packages = (pkg) => `package://${pkg}`;
    this.meshesLoading = 0;
    loader.loadMeshCb = (uri, manager, mat, done) => {
      const url = meshUrls[uri];
      if (!url) {
        onError(`robot ${robot.name}: no URL for mesh ${uri} in robot.mesh_urls`);
        done(null, new Error(`no URL for ${uri}`));
        return;
      }
      this.meshesLoading += 1;
      loader.defaultMeshLoader(url, manager, material || mat, (mesh, err) => {
        this.meshesLoading -= 1;
        if (err) onError(`robot ${robot.name}: mesh ${uri} (${url}) did not load: ${err.message || err}`);
        done(mesh, err);
        if (!err) onMeshLoaded?.();
      });
    };
    this.loader = loader;
    const parsed = loader.parse(robot.urdf);
    if (!parsed || !parsed.isURDFRobot || Object.keys(parsed.links).length === 0) {
      throw new Error(`robot ${robot.name}: the URDF has no links`);
    }
    this.urdf = parsed;
    this.toolLink = robot.tool_link;
    if (!(this.toolLink in parsed.links)) throw new Error(`robot ${robot.name}: the URDF has no tool link ${this.toolLink}`);
    // Lambert rather than the loader's Phong: no specular term, cheaper per pixel without a GPU.
    parsed.traverse((c) => {
      if (!c.isMesh) return;
      const m = c.material;
      c.material = material || new THREE.MeshLambertMaterial({ color: m.color, opacity: m.opacity, transparent: m.transparent, depthWrite: m.depthWrite });
    });
    this.object = new THREE.Group();
    this.object.name = robot.name;
    this.object.add(parsed);
    placeAt(this.object, robot.base_pose);
    this.positions = {};
  }

  /** Apply joint values by name; names the URDF does not have are ignored (the feed may carry others). */
  setJoints(positions) {
    for (const [name, value] of Object.entries(positions)) {
      if (name in this.urdf.joints) {
        this.urdf.setJointValue(name, value);
        this.positions[name] = value;
      }
    }
  }

  get jointNames() { return Object.keys(this.urdf.joints); }

  /** Whether joint ``name`` turns without limits, so that its value wraps around. */
  isContinuous(name) { return this.urdf.joints[name]?.jointType === 'continuous'; }

  /** World pose (document frame) of every link. */
  linkPoses() {
    this.object.updateMatrixWorld(true);
    const out = {};
    for (const [name, link] of Object.entries(this.urdf.links)) out[name] = worldPose(link);
    return out;
  }

  toolPose() { return worldPose(this.urdf.links[this.toolLink]); }

  /** Load a display object's mesh through the same URL map and loaders. */
  loadMesh(uri, done) { this.loader.loadMeshCb(uri, THREE.DefaultLoadingManager, null, (mesh) => done(mesh)); }
}
