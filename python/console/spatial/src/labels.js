// Name labels: DOM elements that follow 3D points (three's CSS2DRenderer), toggled as one.
import { CSS2DObject } from 'three/examples/jsm/renderers/CSS2DRenderer.js';

export function label(text, kind) {
  const div = document.createElement('div');
  div.className = `ct-spatial-label ct-spatial-label-${kind}`;
  div.textContent = text;
  const object = new CSS2DObject(div);
  object.userData.isLabel = true;
  return object;
}
