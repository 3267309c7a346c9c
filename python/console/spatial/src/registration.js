// Registration by dragging. An operator selects a display object or a waypoint, moves a proxy
// with translate/rotate handles and releases: the view asks for the move through
// ``onPoseCommand`` (the page sends it through PAX as that user) and never moves the object
// itself. The proxy stays where it was released, drawn as pending, until an update shows the
// object there (accepted), the page reports the command's failure, or the next update after a
// reported success shows it elsewhere (snap back). Observers get no handles and no commands.
//
// Proposals: where the habitat's camera located the frame a display object is registered to
// (a ``located`` update), the display object is drawn there too, as a cyan wireframe beside
// where it is now. Nothing is registered until the operator accepts it (the same command as a
// drag, as that user) or drags it from there to correct it first; a refusal of the locate shows
// no proposal, and a display object already where perception puts it needs none.
import * as THREE from 'three';
import { TransformControls } from 'three/examples/jsm/controls/TransformControls.js';
import { matrixPose, placeAt, poseDifference, poseInFrame, poseMatrix, rpyOf, worldPose } from './poses.js';

const PENDING = new THREE.MeshBasicMaterial({ color: 0xffd23f, wireframe: true });
const PROPOSED = new THREE.MeshBasicMaterial({ color: 0x3fd0ff, wireframe: true });

/** The SysRep command (affordance_templates) that asks for ``entry`` to be at ``pose`` (document frame). */
export function poseCommand(entry, pose, documentFrame, layer) {
  const t = entry.template;
  let frame; let framePose;
  if (entry.kind === 'display_object') {
    frame = entry.data.parent_frame.name;
    framePose = entry.data.parent_frame.pose;
  } else {
    // frame_id "" = the waypoint's display object, as the AT server reads set_waypoint_pose.
    const parent = entry.data.display_object && layer.get(`${entry.data.display_object}:${t.id}`);
    frame = parent ? '' : documentFrame;
    framePose = parent ? parent.pose : null;
  }
  const local = framePose ? poseInFrame(pose, framePose) : pose;
  const [roll, pitch, yaw] = rpyOf(local);
  const [x, y, z] = local.xyz;
  const common = { affordance_template: t.type, id: t.id, x, y, z, roll, pitch, yaw };
  const args = entry.kind === 'display_object'
    ? { ...common, display_object: entry.data.name, frame }
    : { ...common, trajectory: entry.data.trajectory, waypoint_id: entry.data.index, ee_name: entry.data.ee_name || '', frame_id: frame };
  return {
    command: entry.kind === 'display_object' ? 'set_display_object_pose' : 'set_waypoint_pose',
    target: entry.id,
    template: t.key,
    args,
    pose, // in the document frame
    frame: documentFrame,
    local_pose: local,
    local_frame: frame,
  };
}

export class Registration {
  constructor({ scene, camera, domElement, orbit, layer, documentFrame, onPoseCommand, onError, onChange, pendingTimeoutMs }) {
    Object.assign(this, { scene, layer, documentFrame, onPoseCommand, onError, onChange, pendingTimeoutMs });
    this.canAct = false;
    this.selected = null;
    this.pending = new Map(); // id -> {command, marker, state, since}
    this.located = null; // the last locate result (a ``located`` update's ``located``)
    this.proposals = new Map(); // display object id -> {pose, marker}
    this._settled = new Set(); // ids the operator accepted or corrected from the last result: proposed no more
    this.proxy = new THREE.Group();
    this.proxy.name = 'drag proxy';
    scene.add(this.proxy);
    this.controls = new TransformControls(camera, domElement);
    this.controls.setSize(0.8);
    this.helper = this.controls.getHelper();
    scene.add(this.helper);
    this.controls.addEventListener('dragging-changed', (event) => {
      orbit.enabled = !event.value;
      if (!event.value && this.selected) this.release();
    });
  }

  setCanAct(canAct) {
    this.canAct = !!canAct;
    if (!this.canAct) this.deselect();
  }

  setMode(mode) { this.controls.setMode(mode); this.onChange(); }

  get mode() { return this.controls.getMode(); }

  /** Select entry ``id`` for dragging, from where it is or (``fromProposal``) from where
   * perception proposes it; returns null, or why not. */
  select(id, { fromProposal = false } = {}) {
    if (!this.canAct) return 'this view may only watch: observers cannot move objects';
    const entry = this.layer.get(id);
    if (!entry) return `nothing named ${id}`;
    if (entry.kind === 'display_object' && entry.data.movable === false) return `${id} cannot be moved here: ${entry.data.reason}`;
    const proposal = this.proposals.get(id);
    if (fromProposal && !proposal) return `no proposal for ${id}: perception has not located its frame`;
    this.deselect();
    this.selected = id;
    this.proxy.clear();
    entry.object.children.forEach((c) => { if (!c.userData.isLabel) this.proxy.add(wireCopy(c)); });
    placeAt(this.proxy, fromProposal ? proposal.pose : entry.pose);
    this.controls.attach(this.proxy);
    this.onChange();
    return null;
  }

  deselect() {
    if (this.selected === null) return;
    this.controls.detach();
    this.proxy.clear();
    this.selected = null;
    this.onChange();
  }

  /** Released: ask for the proxy's pose, leave a pending marker there, deselect. A proposal
   * dragged is corrected: what is asked for replaces it. */
  release() {
    const entry = this.layer.get(this.selected);
    if (!entry) { this.deselect(); return null; }
    const released = worldPose(this.proxy);
    const moved = poseDifference(released, entry.pose);
    if (moved.distance < 1e-4 && moved.angle < 1e-4) { this.deselect(); return null; } // a click on a handle asks for nothing
    this.deselect();
    return this._ask(entry, released);
  }

  /** Register display object ``id`` where perception proposes it, as this view's user. */
  accept(id) {
    if (!this.canAct) return { refused: 'this view may only watch: observers cannot accept proposals' };
    const entry = this.layer.get(id);
    const proposal = this.proposals.get(id);
    if (!entry || !proposal) return { refused: `no proposal for ${id}` };
    return { command: this._ask(entry, proposal.pose) };
  }

  /** Send the command that asks for ``entry`` at ``pose``, pending until an update shows it. */
  _ask(entry, pose) {
    const command = poseCommand(entry, pose, this.documentFrame, this.layer);
    if (this.proposals.has(entry.id)) this._settled.add(entry.id);
    this._dropProposal(entry.id);
    this._setPending(entry, command);
    try {
      this.onPoseCommand(command);
    } catch (error) {
      this.onError(`sending ${command.command} for ${entry.id} failed: ${error.message || error}`);
      this.clearPending(entry.id);
    }
    this.onChange();
    return command;
  }

  /** A drag without a pointer: select, move the proxy by ``translate`` (m, document frame) and
   * ``rotate`` (rad, fixed axes about the object's origin), release. Same path as a mouse drag.
   * ``fromProposal``: start from perception's proposal (a correction of it). */
  dragBy(id, { translate = [0, 0, 0], rotate = [0, 0, 0], fromProposal = false } = {}) {
    const refused = this.select(id, { fromProposal });
    if (refused) return { refused };
    const m = poseMatrix(worldPose(this.proxy));
    const p = new THREE.Vector3().setFromMatrixPosition(m);
    const r = new THREE.Matrix4().makeRotationFromEuler(new THREE.Euler(rotate[0], rotate[1], rotate[2], 'ZYX'));
    const rotated = r.multiply(new THREE.Matrix4().extractRotation(m));
    rotated.setPosition(p.add(new THREE.Vector3(...translate)));
    placeAt(this.proxy, matrixPose(rotated));
    return { command: this.release() };
  }

  _setPending(entry, command) {
    this.clearPending(entry.id);
    const marker = new THREE.Group();
    entry.object.children.forEach((c) => { if (!c.userData.isLabel) marker.add(wireCopy(c)); });
    placeAt(marker, command.pose);
    this.scene.add(marker);
    this.pending.set(entry.id, { command, marker, state: 'sent', since: performance.now() });
  }

  clearPending(id) {
    const p = this.pending.get(id);
    if (!p) return;
    this.scene.remove(p.marker);
    this.pending.delete(id);
    this.onChange();
  }

  /** The page's word on a sent command: 'succeeded' waits for the update that shows it;
   * anything else (failed, refused, halted, unknown) drops the pending pose. */
  resolve(id, outcome) {
    const p = this.pending.get(id);
    if (!p) return;
    if (outcome === 'succeeded') p.state = 'succeeded';
    else this.clearPending(id);
  }

  /** After a templates update: pending poses shown by it are accepted; after a reported success,
   * one not shown snaps back. Proposals follow the display objects' registrations. */
  reconcile() {
    for (const [id, p] of [...this.pending]) {
      if (this.layer.at(id, p.command.pose)) this.clearPending(id);
      else if (p.state === 'succeeded' || !this.layer.get(id)) {
        this.clearPending(id);
        this.onError(`${id}: the server shows it elsewhere than requested; it stays where the server has it`);
      }
    }
    this._propose();
  }

  /** A locate result: what perception found, where (``pose``, document frame), or why not. */
  setLocated(located) {
    this.located = located;
    this._settled.clear();
    for (const id of [...this.proposals.keys()]) this._dropProposal(id);
    this._propose();
    this.onChange();
  }

  /** A proposal for each display object registered to the located frame and not already there
   * or asked for: at the pose the camera found the frame in, as a procedure registers it with
   * the located values (the display object is the object itself, whatever its last correction). */
  _propose() {
    const located = this.located;
    if (!located || !located.success || !located.pose) return;
    for (const entry of this.layer.entries.values()) {
      const parent = entry.kind === 'display_object' ? entry.data.parent_frame : null;
      if (!parent || parent.name !== located.object || entry.data.movable === false) continue; // no frame to ask in
      if (this.pending.has(entry.id) || this._settled.has(entry.id)) continue;
      const pose = located.pose;
      const d = poseDifference(pose, entry.pose);
      const old = this.proposals.get(entry.id);
      if (d.distance <= 1e-3 && d.angle <= 1e-2) { this._dropProposal(entry.id); continue; } // already there
      if (old) { placeAt(old.marker, pose); old.pose = pose; continue; }
      const marker = new THREE.Group();
      entry.object.children.forEach((c) => { if (!c.userData.isLabel) marker.add(wireCopy(c, PROPOSED)); });
      marker.name = `proposal ${entry.id}`;
      placeAt(marker, pose);
      this.scene.add(marker);
      this.proposals.set(entry.id, { pose, marker });
    }
  }

  _dropProposal(id) {
    const p = this.proposals.get(id);
    if (!p) return;
    this.scene.remove(p.marker);
    this.proposals.delete(id);
  }

  expire(now) {
    for (const [id, p] of [...this.pending]) {
      if (now - p.since > this.pendingTimeoutMs) {
        this.clearPending(id);
        this.onError(`${id}: no update showed the requested pose within ${Math.round(this.pendingTimeoutMs / 1000)} s`);
      }
    }
  }

  describe() {
    const pending = {};
    for (const [id, p] of this.pending) pending[id] = { state: p.state, pose: p.command.pose, command: p.command.command };
    const proposals = {};
    for (const [id, p] of this.proposals) proposals[id] = { pose: p.pose, object: this.located.object };
    const l = this.located;
    const located = l && { object: l.object, camera: l.camera, success: l.success, message: l.message, residual_px: l.residual_px, offset_mm: l.offset_mm, offset_deg: l.offset_deg, markers: l.markers };
    return { can_act: this.canAct, selected: this.selected, mode: this.mode, pending, proposals, located, handles: this.helper.visible && this.selected !== null };
  }
}

function wireCopy(object, material = PENDING) {
  const copy = object.clone(true);
  copy.traverse((c) => { if (c.isMesh) c.material = material; });
  copy.children.filter((c) => c.userData.isLabel).forEach((c) => copy.remove(c));
  return copy;
}
