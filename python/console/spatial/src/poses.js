// Poses of the contract ({xyz: [x, y, z], quat: [x, y, z, w]}, ROS order) and three.js objects.
// The view keeps ROS axes (z up): the scene graph's coordinates are the document frame's.
import * as THREE from 'three';

/** A Matrix4 of a contract pose. */
export function poseMatrix(pose) {
  const [x, y, z] = pose.xyz;
  const [qx, qy, qz, qw] = pose.quat;
  return new THREE.Matrix4().compose(new THREE.Vector3(x, y, z), new THREE.Quaternion(qx, qy, qz, qw).normalize(), new THREE.Vector3(1, 1, 1));
}

/** The contract pose of a Matrix4 (scale ignored). */
export function matrixPose(matrix) {
  const p = new THREE.Vector3();
  const q = new THREE.Quaternion();
  matrix.decompose(p, q, new THREE.Vector3());
  if (q.w < 0) q.set(-q.x, -q.y, -q.z, -q.w); // one sign, so equal poses compare equal
  return { xyz: [p.x, p.y, p.z], quat: [q.x, q.y, q.z, q.w] };
}

/** Place an Object3D (whose parent sits at the document frame) at a contract pose. */
export function placeAt(object, pose) {
  object.position.set(...pose.xyz);
  object.quaternion.set(...pose.quat).normalize();
  object.updateMatrix();
}

/** World pose of an Object3D as a contract pose. */
export function worldPose(object) {
  object.updateWorldMatrix(true, false);
  return matrixPose(object.matrixWorld);
}

/** ``pose`` expressed in the frame whose world pose is ``frame`` (both in the document frame). */
export function poseInFrame(pose, frame) {
  return matrixPose(poseMatrix(frame).invert().multiply(poseMatrix(pose)));
}

/**
 * Fixed-axis roll, pitch, yaw (R = Rz(yaw) Ry(pitch) Rx(roll), as the SysRep commands and tf
 * take them) of a contract pose's rotation. three's Euler order 'ZYX' is that same product.
 */
export function rpyOf(pose) {
  const e = new THREE.Euler().setFromQuaternion(new THREE.Quaternion(...pose.quat).normalize(), 'ZYX');
  return [e.x, e.y, e.z];
}

/** Distance (m) and angle (rad) between two poses. */
export function poseDifference(a, b) {
  const d = Math.hypot(a.xyz[0] - b.xyz[0], a.xyz[1] - b.xyz[1], a.xyz[2] - b.xyz[2]);
  const dot = Math.abs(a.quat[0] * b.quat[0] + a.quat[1] * b.quat[1] + a.quat[2] * b.quat[2] + a.quat[3] * b.quat[3]);
  return { distance: d, angle: 2 * Math.acos(Math.min(1, dot)) };
}
