"""What the 3D view's names hide, measured in the page: for the fixed-data view and the console alike.

An object's footprint is the set of canvas pixels that change when it is drawn alone or not at
all (the view drawn twice, everything else hidden, read back in the same task): its silhouette,
whatever the arm or a cabinet hides of it. A footprint pixel is covered when a shown name or one
of the view's controls lies over it. Names must not cover each other or the controls either.
"""

from __future__ import annotations

from typing import Any

from playwright.sync_api import Page

#: ``(view) => data``: the view drawn now and its canvas's RGBA pixels, read in the same task (the
#: WebGL buffer is not preserved past it).
READ_PIXELS = """(view) => {
  view.renderer.render(view.scene, view.camera);
  const canvas = view.renderer.domElement;
  const copy = document.createElement('canvas');
  copy.width = canvas.width; copy.height = canvas.height;
  const g = copy.getContext('2d');
  g.drawImage(canvas, 0, 0);
  return g.getImageData(0, 0, copy.width, copy.height).data;
}"""

#: ``(name) => {...}``: the footprint of template object ``name``, how much of it is covered, and
#: the boxes (CSS px in the page) of every shown name and control.
_MEASURE = (
    """(name) => {
  const view = window.caretakerSpatial;
  const entry = view.layer.get(name);
  if (!entry) return {missing: true};
  const canvas = view.renderer.domElement;
  const read = () => ("""
    + READ_PIXELS
    + """)(view);
  // the object's silhouette, drawn alone: names are judged on what they cover, not on what the
  // arm or the cabinet hides of it
  const others = [];
  view.world.traverse((o) => {
    if ((o.isMesh || o.isLine) && o.visible && !o.parent?.userData?.isLabel) {
      let inside = false;
      for (let a = o; a; a = a.parent) if (a === entry.object) inside = true;
      if (!inside) { others.push(o); o.visible = false; }
    }
  });
  const drawn = read();
  entry.object.visible = false;
  const without = read();
  entry.object.visible = true;
  for (const o of others) o.visible = true;
  view.invalidate();
  const box = (e) => {
    const r = e.getBoundingClientRect();
    return {x: r.left, y: r.top, w: r.width, h: r.height, text: e.textContent};
  };
  const shown = (e) => e.offsetParent !== null && e.getBoundingClientRect().width > 0;
  const names = [...view.container.querySelectorAll('.ct-spatial-label')].filter(shown).map(box);
  const controls = [...view.container.querySelectorAll(
    '.ct-spatial-bar button, .ct-spatial-bar input, .ct-spatial-status, .ct-spatial-camera')].filter(shown).map(box);
  const origin = canvas.getBoundingClientRect();
  const scale = canvas.width / origin.width;
  const over = [...names, ...controls];
  let footprint = 0, covered = 0;
  for (let y = 0; y < canvas.height; y += 1) {
    for (let x = 0; x < canvas.width; x += 1) {
      const i = 4 * (y * canvas.width + x);
      const change = Math.abs(drawn[i] - without[i]) + Math.abs(drawn[i + 1] - without[i + 1])
        + Math.abs(drawn[i + 2] - without[i + 2]);
      if (change <= 12) continue;
      footprint += 1;
      const px = origin.left + (x + 0.5) / scale, py = origin.top + (y + 0.5) / scale;
      if (over.some((b) => px >= b.x && px < b.x + b.w && py >= b.y && py < b.y + b.h)) covered += 1;
    }
  }
  return {footprint, covered, names, controls, placed: names.length,
          unplaced: [...view.container.querySelectorAll('.ct-spatial-label[data-placed="no-room"]')].length};
}"""
)


def _overlap(a: dict[str, Any], b: dict[str, Any]) -> bool:
    return (
        a["x"] < b["x"] + b["w"] and b["x"] < a["x"] + a["w"] and a["y"] < b["y"] + b["h"] and b["y"] < a["y"] + a["h"]
    )


def names_hide_nothing(page: Page, name: str, where: str) -> dict[str, Any]:
    """Assert that with names shown at least half of template object ``name`` is visible and that
    no name overlaps another or a control; returns the measurement (printed by the caller)."""
    found = page.evaluate(_MEASURE, name)
    assert not found.get("missing"), f"{where}: no template object {name!r} in the view"
    assert found["footprint"] > 50, f"{where}: {name} covers only {found['footprint']} pixels: not in view"
    visible = 1 - found["covered"] / found["footprint"]
    assert visible >= 0.5, f"{where}: only {visible:.0%} of {name} is visible with names on ({found['names']})"
    names, controls = found["names"], found["controls"]
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not _overlap(a, b), f"{where}: names {a['text']!r} and {b['text']!r} overlap"
        for c in controls:
            assert not _overlap(a, c), f"{where}: name {a['text']!r} lies over the control {c['text']!r}"
    assert names, f"{where}: no name is shown at all"
    found["visible"] = visible
    return found
