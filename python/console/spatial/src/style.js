// The view's own styles, injected once: the bundle is one file and the page needs no CSS for it.
const CSS = `
.ct-spatial { position: relative; overflow: hidden; background: #1d2127; min-height: 200px; font: 12px system-ui, sans-serif; }
.ct-spatial canvas { display: block; }
.ct-spatial.ct-spatial-enlarged { position: fixed !important; inset: 0; width: auto !important; height: auto !important; margin: 0; padding: 0; border: 0; z-index: 1000; border-radius: 0; }
.ct-spatial-labels { position: absolute; top: 0; left: 0; pointer-events: none; }
.ct-spatial-label { position: absolute; top: 0; left: 0; padding: 1px 4px; border-radius: 3px; color: #fff; background: rgba(0, 0, 0, 0.55); white-space: nowrap; }
.ct-spatial-leaders { position: absolute; top: 0; left: 0; overflow: visible; }
.ct-spatial-leaders path { stroke: rgba(255, 255, 255, 0.55); stroke-width: 1; fill: none; }
.ct-spatial-label-display_object { border-left: 3px solid #33e64d; }
.ct-spatial-label-waypoint { border-left: 3px solid #00a0a0; }
.ct-spatial-label-object { color: #ccc; }
.ct-spatial-names-off .ct-spatial-labels { display: none; }
.ct-spatial-bar { position: absolute; left: 6px; right: 6px; bottom: 6px; display: flex; gap: 6px; align-items: center; flex-wrap: wrap; }
.ct-spatial-bar button { background: #2d333b; color: #eee; border: 1px solid #555; border-radius: 4px; padding: 3px 8px; cursor: pointer; }
.ct-spatial-bar button[aria-pressed="true"] { background: #3d6fb4; }
.ct-spatial-bar button:disabled { opacity: 0.4; cursor: default; }
/* the player wraps (its readout under its buttons) rather than run past the view's edge */
.ct-spatial-plan { display: flex; flex-wrap: wrap; gap: 6px; align-items: center; flex: 1 1 240px; min-width: 0; color: #eee; }
.ct-spatial-plan[hidden] { display: none; }
.ct-spatial-plan input[type=range] { flex: 1 1 120px; min-width: 120px; }
.ct-spatial-plan span { overflow-wrap: anywhere; background: rgba(0,0,0,0.5); padding: 1px 4px; border-radius: 3px; }
/* the camera picture top right; the notes (the arm's age, the status line) stacked top left and
   wrapped short of it: at most 70% of the view less both margins and a gap */
.ct-spatial-camera { position: absolute; top: 6px; right: 6px; max-width: 30%; max-height: 45%; border: 1px solid #555; }
.ct-spatial-camera[hidden] { display: none; }
.ct-spatial-notes { position: absolute; top: 6px; left: 6px; max-width: calc(70% - 18px); display: flex; flex-direction: column; align-items: flex-start; gap: 4px; }
.ct-spatial-age, .ct-spatial-status { color: #eee; background: rgba(0,0,0,0.5); padding: 2px 6px; border-radius: 3px; overflow-wrap: anywhere; }
.ct-spatial-age[hidden] { display: none; }
.ct-spatial-status:empty { display: none; }
.ct-spatial-error { color: #ff8a80; }
`;

export function injectStyle() {
  if (document.getElementById('ct-spatial-style')) return;
  const style = document.createElement('style');
  style.id = 'ct-spatial-style';
  style.textContent = CSS;
  document.head.appendChild(style);
}
