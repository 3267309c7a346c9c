// Primitive shapes of the contract as three.js meshes. Geometries are shared per size, so many
// waypoints or filters cost one geometry each kind.
import * as THREE from 'three';
import { placeAt } from './poses.js';

const geometries = new Map();

function shared(key, make) {
  if (!geometries.has(key)) geometries.set(key, make());
  return geometries.get(key);
}

/** A material for an rgba colour; translucent ones do not write depth, so what is inside shows. */
export function material(rgba, { opacity } = {}) {
  const [r, g, b, a] = rgba || [0.7, 0.7, 0.7, 1];
  const alpha = opacity ?? a;
  return new THREE.MeshLambertMaterial({ color: new THREE.Color(r, g, b), transparent: alpha < 1, opacity: alpha, depthWrite: alpha >= 1 });
}

function geometry(shape) {
  switch (shape.type) {
    case 'box': {
      const [x, y, z] = shape.size;
      return shared(`box ${x} ${y} ${z}`, () => new THREE.BoxGeometry(x, y, z));
    }
    case 'sphere': {
      // Marker scale: diameters along x, y, z.
      const [x, y, z] = shape.size;
      return shared(`sphere ${x} ${y} ${z}`, () => new THREE.SphereGeometry(0.5, 24, 16).scale(x, y, z));
    }
    case 'cylinder': {
      // Along z (URDF, pybullet); from a marker scale the diameters are x, y and the length z.
      const [rx, ry, length] = shape.size ? [shape.size[0] / 2, shape.size[1] / 2, shape.size[2]] : [shape.radius, shape.radius, shape.length];
      return shared(`cylinder ${rx} ${ry} ${length}`, () => new THREE.CylinderGeometry(1, 1, length, 32).rotateX(Math.PI / 2).scale(rx, ry, 1));
    }
    default:
      return null;
  }
}

/**
 * An Object3D for one shape of the contract, placed at its pose in its parent. A mesh shape is
 * fetched through ``loadMesh(uri, done)`` (the robot's mesh loader and URL map) and shows a
 * wire box of its size until it arrives.
 */
export function shapeObject(shape, { rgba, opacity, loadMesh } = {}) {
  const mat = material(rgba || shape.rgba, { opacity });
  let object;
  if (shape.type === 'mesh') {
    object = new THREE.Group();
    // A mesh's size is its scale (the AT format's); a small wire box stands in until it arrives.
    const placeholder = new THREE.Mesh(shared('box 0.1 0.1 0.1', () => new THREE.BoxGeometry(0.1, 0.1, 0.1)), new THREE.MeshBasicMaterial({ color: mat.color, wireframe: true }));
    object.add(placeholder);
    loadMesh?.(shape.mesh, (mesh) => {
      if (!mesh) return;
      mesh.traverse((c) => { if (c.isMesh) c.material = mat; });
      mesh.scale.set(...(shape.size || [1, 1, 1]));
      object.remove(placeholder);
      object.add(mesh);
    });
  } else {
    object = new THREE.Mesh(geometry(shape), mat);
  }
  if (shape.pose) placeAt(object, shape.pose);
  return object;
}
