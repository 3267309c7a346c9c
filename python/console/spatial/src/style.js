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
.ct-spatial-plan { display: flex; gap: 6px; align-items: center; flex: 1; color: #eee; }
.ct-spatial-plan[hidden] { display: none; }
.ct-spatial-plan input[type=range] { flex: 1; min-width: 120px; }
.ct-spatial-camera { position: absolute; top: 6px; right: 6px; max-width: 30%; border: 1px solid #555; }
.ct-spatial-camera[hidden] { display: none; }
.ct-spatial-age { position: absolute; top: 6px; left: 6px; color: #eee; background: rgba(0,0,0,0.5); padding: 2px 6px; border-radius: 3px; }
.ct-spatial-age[hidden] { display: none; }
.ct-spatial-status { position: absolute; top: 30px; left: 6px; color: #eee; background: rgba(0,0,0,0.5); padding: 2px 6px; border-radius: 3px; }
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
