// SpatialView: the robot, the scene's objects, the running Affordance Templates and the plan,
// built from the data contract only (README.md). The page owns the data path and the commands:
// it calls load() and apply() with what the ground server sends, and sends what
// onPoseCommand hands it through PAX as the signed-in user.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { CommandedPath } from './commanded_path.js';
import { checkScene, checkUpdate, ContractError } from './contract.js';
import { JointInterpolation } from './joint_interpolation.js';
import { label, LabelLayout } from './labels.js';
import { median } from './median.js';
import { Occluders } from './occluders.js';
import { PlanPlayer } from './plan_player.js';
import { placeAt, worldPose } from './poses.js';
import { Registration } from './registration.js';
import { RobotModel } from './robot_model.js';
import { shapeObject } from './shapes.js';
import { injectStyle } from './style.js';
import { TemplateLayer } from './template_layer.js';
import { Toolbar } from './toolbar.js';

const LATENCY_WINDOW = 50;
// Adaptive resolution: software WebGL (no GPU) composites the canvas per pixel, so a frame's cost
// follows the drawing buffer's size (docs/benchmarks.md: 16 frames/s at 1000x700, 30 at half the
// pixel ratio). While something moves the view draws at a lower resolution if frames cost more
// than FRAME_SLOW_MS, and back up while they cost less than FRAME_FAST_MS; once nothing has moved
// for SETTLE_MS it draws one sharp frame at full resolution, when the operator reads details.
const SETTLE_MS = 300;
const FRAME_SLOW_MS = 1000 / 25;
const FRAME_FAST_MS = 1000 / 45;
const SCALES = [1, 0.85, 0.7, 0.6, 0.5, 0.4, 0.35];
const COST_WINDOW = 8;
// Drawing on demand is capped at this many frames a second (setMaxFrameRate): above the 20 that
// reads as smooth motion, and 2.5 frames for each 10/s joint state. Without a GPU (software WebGL:
// these machines, a ground laptop in a VM) a frame costs about 38 ms of CPU: at the display's 60/s
// the view of a moving arm took nearly two cores, starving the console's other work (docs/benchmarks.md).
const MAX_FRAME_RATE = 25;
// Animation frames come at the display's interval, give or take: a frame due within this much is drawn.
const FRAME_SLACK_MS = 4;
// The arm's age is said four times a second: fresh enough to read, no layout work per frame.
const AGE_EVERY_MS = 250;
// A stamp up to this far ahead of the page's clock is clock error, not a habitat running ahead.
const CLOCK_SLACK_S = 0.5;
// How far the tool drawn moves before what hides it is worked out again (m): a few times over a
// motion, not at every frame.
const TOOL_UNHIDE_M = 0.02;
// Joint states kept as reported, for inspect(): about two seconds at the feed's 10 per second.
const REPORTS_KEPT = 20;

export class SpatialView {
  /**
   * @param {HTMLElement} container where the view draws (it fills it and follows its size)
   * @param {object} options
   *   canAct: whether this user may move things (an operator; observers only watch)
   *   onPoseCommand(command): a drag was released; send command.command with command.args
   *   onError(message): something in the data or a mesh could not be shown
   *   pendingTimeoutMs: how long a requested pose waits for an update showing it (default 60 s)
   *   renderOnDemand: draw only when something changed (default), at most maxFrameRate frames a
   *     second; false draws every animation frame
   *   maxFrameRate: the most frames a second drawn on demand (default 25; Infinity: the display's)
   *   adaptiveResolution: draw at a lower resolution while things move when frames are slow (default)
   *   interpolateJoints: draw the arm moving between joint states (default)
   *   clock: now in ms on the habitat's timeline as this page best knows it (default Date.now;
   *     the console corrects it by its server's clock), for the age of the arm drawn
   */
  constructor(container, { canAct = false, onPoseCommand = () => {}, onError = (m) => console.error(m), pendingTimeoutMs = 60000,
    renderOnDemand = true, maxFrameRate = MAX_FRAME_RATE, adaptiveResolution = true, interpolateJoints = true,
    clock = () => Date.now() } = {}) {
    injectStyle();
    this.container = container;
    container.classList.add('ct-spatial');
    this.onError = (message) => { this.lastError = message; this._status(message, true); onError(message); };
    // No multisampling: with software WebGL (no GPU) it costs a fifth of the frame rate.
    this.renderer = new THREE.WebGLRenderer({ antialias: false });
    this._fullRatio = Math.min(window.devicePixelRatio || 1, 2);
    this.renderer.setPixelRatio(this._fullRatio);
    container.appendChild(this.renderer.domElement);
    this.labels = new LabelLayout();
    container.appendChild(this.labels.domElement);

    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x1d2127);
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
    const sun = new THREE.DirectionalLight(0xffffff, 1.6);
    sun.position.set(3, -4, 6);
    this.scene.add(sun);
    this.camera = new THREE.PerspectiveCamera(50, 1, 0.02, 200);
    this.camera.up.set(0, 0, 1);
    this.camera.position.set(3, -3, 2.5);
    this.orbit = new OrbitControls(this.camera, this.renderer.domElement);
    this.orbit.enableDamping = false;
    this.occluders = new Occluders();
    this.orbit.addEventListener('change', () => { this._unhide(); this._moving(); });

    this.world = new THREE.Group(); // everything from a document; cleared by load()
    this.scene.add(this.world);
    this.layer = null;
    this.player = null;
    this.robot = null;
    this.objects = new Map();
    this.document = null;
    this.namesVisible = true;
    this.enlarged = false;
    // Esc gives the page back from an enlarged view, as a full-screen video does.
    this._onKey = (e) => { if (e.key === 'Escape' && this.enlarged) this.setEnlarged(false); };
    document.addEventListener('keydown', this._onKey);
    this._canAct = !!canAct;
    this._onPoseCommand = onPoseCommand;
    this._pendingTimeoutMs = pendingTimeoutMs;
    this.registration = null;

    // the arm's age above the status line, stacked: a long one pushes the other down (style.js)
    const notes = container.appendChild(Object.assign(document.createElement('div'), { className: 'ct-spatial-notes' }));
    this.statusEl = notes.appendChild(Object.assign(document.createElement('div'), { className: 'ct-spatial-status' }));
    this.cameraImg = document.createElement('img');
    this.cameraImg.className = 'ct-spatial-camera';
    this.cameraImg.alt = 'robot camera';
    this.cameraImg.hidden = true;
    container.appendChild(this.cameraImg);
    // How old the arm drawn is: on a long link it is where it was a light time ago, or more.
    this.ageEl = document.createElement('div');
    this.ageEl.className = 'ct-spatial-age';
    this.ageEl.hidden = true;
    notes.prepend(this.ageEl);
    this._clock = clock;
    this._toolSeenAt = null; // where the tool was when what hides it was last worked out
    this._reports = []; // the last REPORTS_KEPT joint states as reported, for inspect()

    this._frames = 0;
    this._fpsWindow = [];
    this._last = performance.now();
    this._dirty = true;
    this._yieldFrames = 0; // frames left to skip for an emergency action's feedback (yieldFrames)
    this._jointsSince = null; // when the oldest joint update not yet drawn arrived
    this._latencies = []; // joint update -> end of the frame showing it, ms, the last LATENCY_WINDOW
    this.renderOnDemand = !!renderOnDemand;
    this.setMaxFrameRate(maxFrameRate);
    this._dueAt = -Infinity; // when the cap lets the next frame be drawn
    this.adaptiveResolution = !!adaptiveResolution;
    this._interpolateJoints = !!interpolateJoints;
    this._jointMotion = null; // the loaded robot's (load)
    this._armMovedAt = -Infinity; // when a joint state last moved the arm
    this._armMovingSince = null; // when the arm's current motion began
    this._scale = 0; // index into SCALES used while moving
    this._movingUntil = -Infinity;
    this._drawnAt = null; // when the last frame was drawn, until the next animation frame measures its cost
    this._costs = []; // ms from a frame drawn while moving to the next animation frame, the last COST_WINDOW
    this._loop = this._loop.bind(this);
    this._raf = null; // the animation frame requested, while the view has something to draw (_wake)
    // What changes with time alone, with nothing to draw: the arm's age, requests that timed out.
    this._ticker = setInterval(() => {
      this._showAge();
      this.registration?.expire(performance.now());
    }, AGE_EVERY_MS);
    this._installPicking();
    this._resize = new ResizeObserver(() => this._fitCanvas());
    this._resize.observe(container);
    this._fitCanvas();
    window.caretakerSpatial = this; // tests and the console read inspect() here
  }

  // ------------------------------------------------------------------------------ data in

  /** Build the view from a scene document; a malformed one is refused whole (ContractError). */
  load(doc) {
    let robot;
    try {
      checkScene(doc);
      robot = new RobotModel(doc.robot, { onError: this.onError, onMeshLoaded: () => this.invalidate() });
    } catch (error) {
      this.onError(`scene document refused: ${error.message}`);
      throw error;
    }
    this._clear();
    this.document = doc;
    this.robot = robot;
    this.world.add(robot.object);
    robot.setJoints(doc.joints.positions);
    this._jointMotion = new JointInterpolation((name) => robot.isContinuous(name));
    this.joints = { stamp: 0, positions: {} };
    this._reported(doc.joints.positions, doc.joints.stamp);
    const objects = new THREE.Group();
    objects.name = 'objects';
    for (const o of doc.objects) {
      const group = new THREE.Group();
      group.name = o.name;
      for (const s of o.shapes) group.add(shapeObject(s, { loadMesh: (uri, done) => robot.loadMesh(uri, done) }));
      // The name at the middle of the shapes: a body's origin may lie far from them (a hull at 0).
      const name = label(o.name, 'object');
      name.position.copy(new THREE.Box3().setFromObject(group).getCenter(new THREE.Vector3()));
      group.add(name);
      placeAt(group, o.pose);
      objects.add(group);
      this.objects.set(o.name, { object: group, pose: o.pose, kind: o.kind || 'object' });
    }
    this.world.add(objects);
    this.occluders.watch(objects);
    this.layer = new TemplateLayer({ loadMesh: (uri, done) => robot.loadMesh(uri, done) });
    this.world.add(this.layer.group);
    this.player = new PlanPlayer(doc.robot, { onError: this.onError, onChange: () => this._changed() });
    this.world.add(this.player.object);
    this.commanded = new CommandedPath();
    this.world.add(this.commanded.object);
    this.registration = new Registration({
      scene: this.world,
      camera: this.camera,
      domElement: this.renderer.domElement,
      orbit: this.orbit,
      layer: this.layer,
      documentFrame: doc.frame,
      onPoseCommand: this._onPoseCommand,
      onError: this.onError,
      onChange: () => this._changed(),
      pendingTimeoutMs: this._pendingTimeoutMs,
    });
    this.registration.controls.addEventListener('change', () => this._moving()); // drags, handle hover
    this.registration.setCanAct(this._canAct);
    if (!this.toolbar) this.toolbar = new Toolbar(this.container, this);
    this.layer.update(doc.templates);
    this._showPlan(doc.plan);
    this._camera(doc.camera?.url ?? null);
    this._status('');
    this.viewpoint = doc.viewpoint || null;
    this.home();
    this._changed();
    return this;
  }

  /** Apply one update; a malformed one is reported through onError and changes nothing. */
  apply(update) {
    if (!this.document) { this.onError('update before any scene document'); return false; }
    try {
      checkUpdate(update);
    } catch (error) {
      if (!(error instanceof ContractError)) throw error;
      this.onError(`update refused: ${error.message}`);
      return false;
    }
    switch (update.kind) {
      case 'joints': {
        // The habitat sends joint states while the arm stands still too: those change no pixel.
        const now = performance.now();
        const moved = Object.entries(update.positions).some(([name, value]) => this.joints.positions[name] !== value);
        const interval = this._jointMotion.arrived(now);
        this._reported(update.positions, update.stamp);
        this.jointUpdates = (this.jointUpdates || 0) + 1;
        if (this.commanded.plan && !this.commanded.reached) {
          // the ghost is hidden while a plan runs: it serves to place the tool as reported
          this.player.ghost.setJoints(this.joints.positions);
          if (this.commanded.reported(this.player.ghost.toolPose().xyz)) this._changed();
        }
        if (!moved) return true;
        if (now - this._armMovedAt > SETTLE_MS) this._armMovingSince = now;
        this._armMovedAt = now;
        const drawNow = this._jointMotion.toward(this.robot.positions, update.positions, now, this._interpolateJoints ? interval : 0);
        if (drawNow) this._drawArm(drawNow);
        this._jointsSince ??= now;
        this._moving();
        break;
      }
      case 'objects':
        for (const [name, pose] of Object.entries(update.poses)) {
          const o = this.objects.get(name);
          if (o) { placeAt(o.object, pose); o.pose = pose; }
        }
        this._unhide();
        break;
      case 'templates':
        this.layer.update(update.templates);
        if (this.registration.selected && !this.layer.get(this.registration.selected)) this.registration.deselect();
        this.registration.reconcile();
        this._unhide();
        break;
      case 'plan':
        this._showPlan(update.plan);
        break;
      case 'camera':
        this._camera(update.url);
        break;
      case 'located':
        this.registration.setLocated(update.located);
        this._status(locatedText(update.located, this.registration.proposals.size));
        break;
      default:
        break;
    }
    this._changed();
    return true;
  }

  // ---------------------------------------------------------------------------- controls

  setCanAct(canAct) {
    this._canAct = !!canAct;
    this.registration?.setCanAct(this._canAct);
    this._changed();
  }

  /** The page's word on a command onPoseCommand handed it (succeeded, failed, unknown, halted). */
  resolvePending(id, outcome) { this.registration?.resolve(id, outcome); this._changed(); }

  select(id) { return this.registration ? this.registration.select(id) : 'no scene loaded'; }

  /** A drag without a pointer (tests, keyboard nudges): same path as releasing a handle. */
  dragBy(id, motion) { return this.registration ? this.registration.dragBy(id, motion) : { refused: 'no scene loaded' }; }

  /** Register display object ``id`` where perception proposes it (every proposal without ``id``). */
  accept(id) {
    if (!this.registration) return { refused: 'no scene loaded' };
    const ids = id === undefined ? [...this.registration.proposals.keys()] : [id];
    if (ids.length === 0) return { refused: 'no proposal to accept' };
    const answers = ids.map((one) => this.registration.accept(one));
    const refused = answers.find((a) => a.refused);
    if (refused) this._status(refused.refused);
    return ids.length === 1 ? answers[0] : { commands: answers };
  }

  stepWaypoint(direction) { this.player?.stepWaypoint(direction); }

  /** Something drawn changed outside the view's own paths (the page's doing): draw the next frame. */
  invalidate() { this._dirty = true; this._wake(); }

  /**
   * Draw nothing in the next `frames` animation frames: the frame that shows an operator's
   * emergency action (HALT's "halting…") must not wait for this view, which drawn in software
   * takes tens of ms a frame while the arm moves. The view catches up in the frame after.
   */
  yieldFrames(frames = 1) { this._yieldFrames = Math.max(this._yieldFrames, frames); }

  /** Adaptive resolution on (default) or off: the benchmark compares both in one page. */
  setAdaptiveResolution(adaptive) {
    this.adaptiveResolution = !!adaptive;
    this._costs = [];
    this.invalidate();
  }

  /** Joints drawn moving between states (default) or each state as it arrives: the benchmark compares both. */
  setJointInterpolation(interpolate) {
    this._interpolateJoints = !!interpolate;
    this._latencies = [];
  }

  /** On demand (default) or every animation frame: the benchmark compares both in one page. */
  setRenderOnDemand(onDemand) {
    this.renderOnDemand = !!onDemand;
    this._latencies = [];
    this.invalidate();
  }

  /** At most ``fps`` frames a second drawn on demand (Infinity: one every animation frame that has news). */
  setMaxFrameRate(fps) {
    if (!(fps > 0)) throw new RangeError(`maxFrameRate: expected a number of frames a second above 0, got ${fps}`);
    this.maxFrameRate = fps;
    this._frameEveryMs = 1000 / fps;
  }

  setNamesVisible(visible) {
    this.namesVisible = !!visible;
    this.container.classList.toggle('ct-spatial-names-off', !this.namesVisible);
    this._changed();
  }

  /** A plan before it runs is the ghost to play; while it runs (``commanded``) the path ahead of the arm. */
  _showPlan(plan) {
    if (plan && plan.commanded) {
      this.commanded.set(plan, this.player.ghost, this.joints.positions);
      this.player.setPlan(null, this.joints.positions);
    } else {
      this.commanded.clear();
      this.player.setPlan(plan, this.joints.positions);
    }
  }

  /** Fill the window with the view (``true``), or put it back in its panel; Esc also puts it back. */
  setEnlarged(enlarged) {
    this.enlarged = !!enlarged;
    const el = this.container;
    el.classList.toggle('ct-spatial-enlarged', this.enlarged);
    // In the top layer (a popover) the view is above the page whatever stacking contexts hold
    // it: a sticky panel or header would otherwise still draw over a fixed element inside it.
    if (typeof el.showPopover === 'function') {
      if (this.enlarged) {
        el.setAttribute('popover', 'manual');
        el.showPopover();
      } else if (el.hasAttribute('popover')) {
        el.hidePopover();
        el.removeAttribute('popover');
      }
    }
    this._changed(); // the resize observer refits the canvas to the new size
  }

  /** The document's viewpoint (the scene's own camera), or a framing of the work when it has none. */
  home() {
    const v = this.viewpoint;
    if (!v) { this.fit(); return; }
    this.camera.fov = v.fov_deg || 50;
    this._look(new THREE.Vector3(...v.eye), new THREE.Vector3(...v.target));
  }

  /** Frame the work: the robot, the templates and the ghost, seen from the viewpoint's side. */
  fit() {
    const box = new THREE.Box3();
    this.world.updateMatrixWorld(true);
    for (const part of [this.robot?.object, this.layer?.group, this.player?.object]) if (part && part.visible) box.expandByObject(part);
    if (box.isEmpty()) return;
    const sphere = box.getBoundingSphere(new THREE.Sphere());
    const distance = sphere.radius / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2));
    const v = this.viewpoint;
    const direction = v ? new THREE.Vector3(...v.eye).sub(new THREE.Vector3(...v.target)).normalize() : new THREE.Vector3(-1, -1.2, 0.9).normalize();
    this._look(sphere.center.clone().addScaledVector(direction, distance), sphere.center);
  }

  /** Look from ``eye`` at ``target`` (world [x, y, z]), as an operator orbiting there would. */
  look(eye, target) { this._look(new THREE.Vector3(...eye), new THREE.Vector3(...target)); }

  _look(eye, target) {
    const distance = eye.distanceTo(target);
    this.camera.position.copy(eye);
    this.orbit.target.copy(target);
    this.camera.near = Math.max(0.01, distance / 500);
    this.camera.far = Math.max(50, distance * 20);
    this.camera.updateProjectionMatrix();
    this.orbit.update();
    this._unhide();
  }

  _unhide() {
    const targets = [this.orbit.target.clone()];
    if (this.layer) for (const e of this.layer.entries.values()) targets.push(new THREE.Vector3(...e.pose.xyz));
    // The gripper at work: reaching into a cabinet it would otherwise vanish behind the housing.
    if (this.robot) {
      this._toolSeenAt = new THREE.Vector3(...this.robot.toolPose().xyz);
      targets.push(this._toolSeenAt.clone());
    }
    this.occluders.update(this.camera.position, targets);
  }

  /** Draw the arm at ``positions``; what hides its tool is worked out again once it moved TOOL_UNHIDE_M. */
  _drawArm(positions) {
    this.robot.setJoints(positions);
    const tool = new THREE.Vector3(...this.robot.toolPose().xyz);
    if (!this._toolSeenAt || tool.distanceTo(this._toolSeenAt) >= TOOL_UNHIDE_M) this._unhide();
  }

  dispose() {
    cancelAnimationFrame(this._raf);
    clearInterval(this._ticker);
    this._resize.disconnect();
    document.removeEventListener('keydown', this._onKey);
    this.orbit.dispose();
    this.registration?.controls.dispose();
    this.renderer.dispose();
    this.container.replaceChildren();
  }

  // ------------------------------------------------------------------------ introspection

  /** What tests (and a curious page) may read: poses in the document frame, state, frame rate. */
  inspect() {
    const now = performance.now();
    if (!this.document) return { loaded: false, fps: this.fps ?? 0, frames: this._frames };
    const objects = {};
    for (const [name, o] of this.objects) objects[name] = { kind: o.kind, pose: worldPose(o.object) };
    const templates = {};
    for (const [id, e] of this.layer.entries) templates[id] = { kind: e.kind, template: e.template.key, pose: worldPose(e.object), visible: e.object.visible };
    return {
      loaded: true,
      frame: this.document.frame,
      robot: this.document.robot.name,
      links: this.robot.linkPoses(),
      joints: { ...this.robot.positions },
      joint_updates: this.jointUpdates || 0,
      joints_drawn: { ...this.robot.positions },
      joints_reported_recently: this._reports.map((r) => ({ ...r })),
      arm_age_s: this._age(),
      commanded: this.commanded.describe(),
      arm_moving_ms: now - this._armMovedAt <= SETTLE_MS ? now - this._armMovingSince : 0,
      tool_pose: this.robot.toolPose(),
      objects,
      templates,
      ghost: this.player.describe(),
      registration: this.registration.describe(),
      names_visible: this.namesVisible,
      enlarged: this.enlarged,
      camera: { eye: this.camera.position.toArray(), target: this.orbit.target.toArray(), faded: this.occluders.faded() },
      camera_url: this.cameraImg.hidden ? null : this.cameraImg.getAttribute('src'),
      fps: this.fps ?? 0,
      frames: this._frames,
      // everything there is to draw has been drawn: no change waiting, no arm still drawn moving
      // toward a joint state (each frame of that move is drawn at once), no mesh still loading
      settled: this._frames > 0 && !this._dirty && !this._jointMotion.moving
        && this.robot.meshesLoading + this.player.ghost.meshesLoading === 0,
      render_on_demand: this.renderOnDemand,
      max_frame_rate: this.maxFrameRate,
      animating: this._raf !== null, // the loop waits for an animation frame: the view has something to draw
      adaptive_resolution: this.adaptiveResolution,
      joint_interpolation: this._interpolateJoints,
      resolution_scale: this.renderer.getPixelRatio() / this._fullRatio,
      update_latency_ms: median(this._latencies),
      last_error: this.lastError ?? null,
    };
  }

  /** Where entry or object ``name`` appears in the page (client px), to aim a pointer at it. */
  screenPoint(name) {
    const target = this.layer?.get(name)?.object || this.objects.get(name)?.object;
    if (!target) return null;
    const p = new THREE.Vector3().setFromMatrixPosition(target.matrixWorld).project(this.camera);
    const rect = this.renderer.domElement.getBoundingClientRect();
    return { x: rect.left + ((p.x + 1) / 2) * rect.width, y: rect.top + ((1 - p.y) / 2) * rect.height };
  }

  // ------------------------------------------------------------------------------ private

  _clear() {
    this.registration?.deselect();
    if (this.registration) { this.registration.controls.dispose(); this.scene.remove(this.registration.helper); }
    this.world.clear();
    this.objects.clear();
  }

  _camera(url) {
    this.cameraImg.hidden = !url;
    if (url) this.cameraImg.src = url;
    else this.cameraImg.removeAttribute('src');
  }

  _status(text, error = false) {
    this.statusEl.textContent = text;
    this.statusEl.classList.toggle('ct-spatial-error', error);
  }

  _changed() { this.toolbar?.refresh(); this.invalidate(); }

  /** Something on screen moves (joints, camera, a handle): draw it, at the moving resolution until it settles. */
  _moving() {
    this._movingUntil = performance.now() + SETTLE_MS;
    this.invalidate();
  }

  _isMoving(now) { return now < this._movingUntil || !!this.player?.playing; }

  /** The cost of the frame drawn last (from its draw to this animation frame), counted while things move. */
  _measureCost(now) {
    if (this._drawnAt !== null && this._isMoving(now)) {
      this._costs.push(now - this._drawnAt);
      if (this._costs.length >= COST_WINDOW) {
        const cost = median(this._costs);
        const step = cost > FRAME_SLOW_MS ? 1 : cost < FRAME_FAST_MS ? -1 : 0;
        this._scale = Math.min(SCALES.length - 1, Math.max(0, this._scale + step));
        this._costs = [];
      }
    }
    this._drawnAt = null;
  }

  /** The pixel ratio to draw this frame at: lower while moving if frames are slow, full when still. */
  _adaptResolution(now) {
    const ratio = this._fullRatio * (this.adaptiveResolution && this._isMoving(now) ? SCALES[this._scale] : 1);
    if (ratio !== this.renderer.getPixelRatio()) {
      this.renderer.setPixelRatio(ratio); // resizes the drawing buffer, not the canvas on the page
      this._dirty = true; // settling: one sharp frame
    }
  }

  /** The view's controls and notes as boxes in view px, for names to stay clear of. */
  _controlBoxes() {
    const origin = this.container.getBoundingClientRect();
    const boxes = [];
    for (const el of [this.toolbar?.bar, this.statusEl, this.cameraImg, this.ageEl]) {
      if (!el || el.hidden || !el.offsetParent) continue; // not shown (an empty status is display: none)
      const r = el.getBoundingClientRect();
      if (r.width && r.height) boxes.push({ x: r.left - origin.left, y: r.top - origin.top, w: r.width, h: r.height });
    }
    return boxes;
  }

  /** A joint state the habitat reported (in the scene document or the feed): kept, and its age said
   * at once, so the page never shows an arm without saying how old it is (the frame may come late). */
  _reported(positions, stamp) {
    Object.assign(this.joints.positions, positions);
    this.joints.stamp = stamp ?? this.joints.stamp;
    this._reports.push({ ...this.joints.positions });
    if (this._reports.length > REPORTS_KEPT) this._reports.shift();
    this._showAge();
  }

  /** Seconds since the arm drawn was where it is (its joint state's stamp), or null before one came. */
  _age() {
    if (!this.joints || !this.joints.stamp) return null;
    return this._clock() / 1000 - this.joints.stamp;
  }

  _showAge() {
    const age = this._age();
    this.ageEl.hidden = age === null;
    if (age === null) return;
    // A stamp ahead of this clock: the habitat's clock runs ahead (a simulation faster than real time).
    const text = age >= -CLOCK_SLACK_S ? `arm as reported ${Math.max(0, age).toFixed(1)} s ago` : "arm as last reported (the habitat's clock is ahead of this one)";
    if (this.ageEl.textContent !== text) this.ageEl.textContent = text;
  }

  _fitCanvas() {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(w, h);
    this.labels.setSize(w, h);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    this.invalidate();
  }

  _installPicking() {
    const el = this.renderer.domElement;
    let down = null;
    el.addEventListener('pointerdown', (e) => { down = [e.clientX, e.clientY]; });
    el.addEventListener('pointerup', (e) => {
      if (!down || !this.layer || Math.hypot(e.clientX - down[0], e.clientY - down[1]) > 4) return;
      if (this.registration.controls.dragging || this.registration.controls.axis) return;
      const rect = el.getBoundingClientRect();
      const ndc = new THREE.Vector2(((e.clientX - rect.left) / rect.width) * 2 - 1, -((e.clientY - rect.top) / rect.height) * 2 + 1);
      const ray = new THREE.Raycaster();
      ray.setFromCamera(ndc, this.camera);
      // Meshes only: the waypoints' axes are lines, which a ray 'hits' from far around them.
      const hit = ray.intersectObject(this.layer.group, true).find((h) => h.object.isMesh && this.layer.entryOf(h.object));
      if (!hit) { this.registration.deselect(); return; }
      const refused = this.registration.select(this.layer.entryOf(hit.object).id);
      if (refused) this._status(refused);
    });
  }

  /**
   * Run the loop from the next animation frame, unless it runs. It runs only while the view has
   * something to draw (_busy): a page asking for every animation frame keeps Chromium making
   * frames, 5 % of a core for an idle view drawn in software (docs/benchmarks.md).
   */
  _wake() {
    if (this._raf !== null) return;
    this._last = performance.now();
    this._drawnAt = null; // the pause since the last frame is not that frame's cost
    this._raf = requestAnimationFrame(this._loop);
  }

  /** Whether the loop has more to do after the animation frame at ``now``. */
  _busy(now) {
    return !this.renderOnDemand || this._dirty || this._yieldFrames > 0 || !!this._jointMotion?.moving
      || this._isMoving(now) || this.renderer.getPixelRatio() !== this._fullRatio;
  }

  _loop(now) {
    this._raf = null;
    this._frame(now);
    if (this._raf === null && this._busy(now)) this._raf = requestAnimationFrame(this._loop);
  }

  _frame(now) {
    this._measureCost(now);
    // Within the cap nothing moves either: what inspect() says is drawn has been drawn.
    if (this.renderOnDemand && now < this._dueAt - FRAME_SLACK_MS) return;
    const dt = Math.min(0.1, (now - this._last) / 1000);
    this._last = now;
    if (this.player?.playing) { this.player.tick(dt); this._dirty = true; }
    const joints = this._jointMotion?.at(now);
    if (joints) { this._drawArm(joints); this._moving(); }
    this._adaptResolution(now); // after the arm's step: a frame that moves it is drawn as moving
    // On demand: a frame only when something changed (a mesh that finished loading says so too).
    // An idle view then costs nothing: drawn in software, each frame of it was tens of ms of CPU.
    if (this._yieldFrames > 0) { this._yieldFrames -= 1; return; } // still dirty: drawn next frame
    if (this.renderOnDemand && !this._dirty) return;
    this._dirty = false;
    // On the cap's own cadence while frames follow each other (25/s from a 60/s display: every
    // second or third animation frame); from now after a pause.
    this._dueAt = (now - this._dueAt > this._frameEveryMs ? now : this._dueAt) + this._frameEveryMs;
    this.renderer.render(this.scene, this.camera);
    this._drawnAt = now;
    if (this.namesVisible) this.labels.render(this.scene, this.camera, this._controlBoxes());
    if (this._jointsSince !== null) {
      this._latencies.push(performance.now() - this._jointsSince);
      if (this._latencies.length > LATENCY_WINDOW) this._latencies.shift();
      this._jointsSince = null;
    }
    this._frames += 1;
    this._fpsWindow.push(now);
    while (this._fpsWindow.length && now - this._fpsWindow[0] > 1000) this._fpsWindow.shift();
    this.fps = this._fpsWindow.length;
  }
}


/** What the view says of a locate result: where perception found the object, or why not. */
function locatedText(located, proposals) {
  if (!located.success) return `not registered: ${located.message}`;
  const found = `${located.object} located by ${located.camera}: ${located.offset_mm.toFixed(1)} mm, `
    + `${located.offset_deg.toFixed(1)}° from the drawings (${located.residual_px.toFixed(2)} px)`;
  return proposals > 0 ? `${found}; proposed in cyan: Accept, or drag it to correct` : found;
}
