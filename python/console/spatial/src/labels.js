// Names, placed where they hide nothing the operator works with.
//
// A name at its object's centre (three's CSS2DRenderer) covers that object: with names on, the
// display object an operator registers was entirely under its own name, names lay on each other
// and on the view's buttons. Here, after each frame, every name is put beside what it names: clear
// of that object's box on the screen, of every template display object, of the names already
// placed and of the view's controls, joined to its object by a leader line. A name that finds no
// clear place is not shown (its object still is). Display objects' names are placed first, then
// waypoints', then the scene's objects', nearest first within each.
import * as THREE from 'three';

/** A name for the object it is added to (its parent); ``kind`` says whose: display_object, waypoint or object. */
export function label(text, kind) {
  const element = document.createElement('div');
  element.className = `ct-spatial-label ct-spatial-label-${kind}`;
  element.textContent = text;
  const carrier = new THREE.Object3D(); // where the name is anchored; drawn only as its element
  carrier.userData.isLabel = true;
  carrier.userData.kind = kind;
  carrier.userData.element = element;
  return carrier;
}

const ORDER = { display_object: 0, waypoint: 1, object: 2 };
const GAPS = [4, 28]; // px between a name and its object's box: close first, then further out
const MARGIN = 2; // px kept clear around names and controls
const PART = new THREE.Box3();

function overlaps(a, b) {
  return a.x < b.x + b.w + MARGIN && b.x < a.x + a.w + MARGIN && a.y < b.y + b.h + MARGIN && b.y < a.y + a.h + MARGIN;
}

/** The box of ``object``'s shapes on the screen (px in a w x h view), or null when behind the camera. */
function screenBox(object, camera, w, h, box, corner) {
  box.makeEmpty();
  object.traverseVisible((o) => {
    if (o.userData.isLabel || !o.geometry) return;
    if (!o.geometry.boundingBox) o.geometry.computeBoundingBox();
    box.union(PART.copy(o.geometry.boundingBox).applyMatrix4(o.matrixWorld));
  });
  if (box.isEmpty()) box.setFromCenterAndSize(object.getWorldPosition(corner), new THREE.Vector3());
  let x0 = Infinity, y0 = Infinity, x1 = -Infinity, y1 = -Infinity;
  for (let i = 0; i < 8; i += 1) {
    corner.set(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z);
    corner.applyMatrix4(camera.matrixWorldInverse);
    if (corner.z > -camera.near) return null; // a corner behind the camera: no sensible box
    corner.applyMatrix4(camera.projectionMatrix);
    const x = ((corner.x + 1) / 2) * w, y = ((1 - corner.y) / 2) * h;
    x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
  }
  if (x1 < 0 || y1 < 0 || x0 > w || y0 > h) return null; // off the view
  return { x: x0, y: y0, w: x1 - x0, h: y1 - y0 };
}

/** Where a name of size (lw, lh) may go around box ``b``: above, below, right, left, the corners. */
function* candidates(b, lw, lh) {
  const cx = b.x + b.w / 2 - lw / 2, cy = b.y + b.h / 2 - lh / 2;
  for (const g of GAPS) {
    yield { x: cx, y: b.y - g - lh };
    yield { x: cx, y: b.y + b.h + g };
    yield { x: b.x + b.w + g, y: cy };
    yield { x: b.x - g - lw, y: cy };
    yield { x: b.x + b.w + g, y: b.y - g - lh };
    yield { x: b.x - g - lw, y: b.y - g - lh };
    yield { x: b.x + b.w + g, y: b.y + b.h + g };
    yield { x: b.x - g - lw, y: b.y + b.h + g };
  }
}

/** The nearest point of box ``b`` to point (x, y). */
function nearest(b, x, y) {
  return [Math.min(Math.max(x, b.x), b.x + b.w), Math.min(Math.max(y, b.y), b.y + b.h)];
}

export class LabelLayout {
  constructor() {
    this.domElement = document.createElement('div');
    this.domElement.className = 'ct-spatial-labels';
    this.lines = document.createElementNS('http://www.w3.org/2000/svg', 'svg');
    this.lines.setAttribute('class', 'ct-spatial-leaders');
    this.domElement.appendChild(this.lines);
    this.width = 1;
    this.height = 1;
    this._sizes = new WeakMap(); // element -> {text, w, h}
    this._box = new THREE.Box3();
    this._corner = new THREE.Vector3();
    this._world = new THREE.Vector3();
  }

  setSize(w, h) {
    this.width = w;
    this.height = h;
    this.domElement.style.width = `${w}px`;
    this.domElement.style.height = `${h}px`;
    this.lines.setAttribute('width', String(w));
    this.lines.setAttribute('height', String(h));
  }

  /** Place every visible name of ``scene`` clear of ``avoid`` (boxes in view px: the controls). */
  render(scene, camera, avoid = []) {
    const { width: w, height: h } = this;
    const names = [];
    scene.traverseVisible((o) => {
      if (!o.userData.isLabel || !o.parent) return;
      const subject = screenBox(o.parent, camera, w, h, this._box, this._corner);
      const element = o.userData.element;
      if (element.parentNode !== this.domElement) this.domElement.appendChild(element);
      const distance = o.getWorldPosition(this._world).distanceTo(camera.position);
      names.push({ element, kind: o.userData.kind, subject, distance });
    });
    // Read every size before writing any position: one layout for the whole frame.
    for (const n of names) n.size = this._size(n.element);
    const shown = new Set(names.map((n) => n.element));
    for (const child of [...this.domElement.children]) {
      if (child !== this.lines && !shown.has(child)) child.remove(); // its object left the scene
    }
    const keepClear = [...avoid];
    for (const n of names) if (n.kind === 'display_object' && n.subject) keepClear.push(n.subject);
    names.sort((a, b) => (ORDER[a.kind] ?? 3) - (ORDER[b.kind] ?? 3) || a.distance - b.distance);
    const placed = [];
    const leaders = [];
    for (const n of names) {
      const spot = n.subject && this._clearSpot(n, keepClear, placed);
      const style = n.element.style;
      if (!spot) {
        style.display = 'none';
        n.element.dataset.placed = 'no-room';
        continue;
      }
      placed.push(spot);
      style.display = '';
      style.transform = `translate(${Math.round(spot.x)}px, ${Math.round(spot.y)}px)`;
      n.element.dataset.placed = 'clear';
      const [ax, ay] = nearest(n.subject, spot.x + spot.w / 2, spot.y + spot.h / 2);
      const [lx, ly] = nearest(spot, ax, ay);
      leaders.push(`M${lx.toFixed(1)} ${ly.toFixed(1)}L${ax.toFixed(1)} ${ay.toFixed(1)}`);
    }
    this._path().setAttribute('d', leaders.join(''));
  }

  _clearSpot(n, keepClear, placed) {
    const { w: lw, h: lh } = n.size;
    for (const c of candidates(n.subject, lw, lh)) {
      const spot = { x: c.x, y: c.y, w: lw, h: lh };
      if (spot.x < MARGIN || spot.y < MARGIN || spot.x + lw > this.width - MARGIN || spot.y + lh > this.height - MARGIN) continue;
      if (overlaps(spot, n.subject) || keepClear.some((b) => overlaps(spot, b)) || placed.some((b) => overlaps(spot, b))) continue;
      return spot;
    }
    return null;
  }

  _size(element) {
    const known = this._sizes.get(element);
    if (known && known.text === element.textContent) return known;
    element.style.display = '';
    const size = { text: element.textContent, w: element.offsetWidth, h: element.offsetHeight };
    this._sizes.set(element, size);
    return size;
  }

  _path() {
    if (!this._leader) {
      this._leader = document.createElementNS('http://www.w3.org/2000/svg', 'path');
      this.lines.appendChild(this._leader);
    }
    return this._leader;
  }
}
