"""The console's layout at the widths operators use: nothing lies over anything.

At 900, 1024, 1280, 1500 and 1920 px, with the 3D view, with it enlarged and without it: no two of
the console's panels (header, runs list, procedure, side column) intersect at any scroll position,
the 3D view's overlays (the arm's age, the status line, the camera picture, the controls and the
plan player's readout) lie inside the view and clear of each other, nothing runs past the window's
right edge, and every control can be scrolled to where a click reaches it (nothing covers it).

One page, resized through the widths. The run is on the simulated systems (conftest.py's server);
the 3D view's feed (``/ws/runs/ID/spatial``) is played by the test with a scene, a running
template, its plan, a camera picture and a perception result made by the real producers from the
shipped IVA scene (spatial_data.py), so no robot stack is needed. Screenshots:
console-layout-WIDTH.png and console-layout-enlarged.png (``make docs`` puts them in docs/images).
"""

from __future__ import annotations

import base64
import json
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest
from playwright.sync_api import Browser, Page, WebSocketRoute, expect
from spatial_data import REPO, Habitat, RunningTemplate

from console.spatial_updates import located_update
from support.browser import signed_in_pages
from support.operator_page import IVA, screenshot, sign_in_on, start_run, stop_run
from support.web_server import WebServer

pytestmark = pytest.mark.slow(seconds=25)

#: Width and height of each window: a small laptop, the classic console, and the usual desktops.
WINDOWS = [(900, 700), (1024, 768), (1280, 800), (1500, 1000), (1920, 1080)]
#: The status line at its longest in practice: a perception result that did not register.
NOT_LOCATED = "two of the four markers are hidden by the arm; move it clear of the filter and locate again"

#: ``(enlarged) => [problems]``: what lies over what, measured in the page (CSS px, a half pixel of
#: rounding allowed). Panels at every scroll position from the top to the bottom of the page; the
#: view's overlays as they are; then every shown control scrolled into the middle of the window
#: (of the view's, the view) and hit-tested at its centre. Enlarged, the view covers the page by
#: design: only the view is measured.
MEASURE = """(enlarged) => {
  const problems = [];
  const rect = (e) => { const r = e.getBoundingClientRect(); return {x: r.left, y: r.top, w: r.width, h: r.height}; };
  const shown = (e) => e.checkVisibility() && rect(e).w > 0 && rect(e).h > 0;
  const meet = (a, b) =>
    a.x < b.x + b.w - 0.5 && b.x < a.x + a.w - 0.5 && a.y < b.y + b.h - 0.5 && b.y < a.y + a.h - 0.5;
  const within = (a, o) =>
    a.x >= o.x - 0.5 && a.y >= o.y - 0.5 && a.x + a.w <= o.x + o.w + 0.5 && a.y + a.h <= o.y + o.h + 0.5;
  const name = (e) => e.id ? '#' + e.id
    : `${e.tagName.toLowerCase()}${e.getAttribute('class') ? '.' + e.getAttribute('class').trim().split(' ')[0] : ''}`
      + (e.textContent.trim() ? ` "${e.textContent.trim().replace(/\\s+/g, ' ').slice(0, 30)}"` : '');
  const pairs = (items, where) => {
    for (let i = 0; i < items.length; i += 1)
      for (const other of items.slice(i + 1))
        if (meet(rect(items[i]), rect(other))) problems.push(`${where}: ${name(items[i])} and ${name(other)} overlap`);
  };
  const innerScrolls = () => document.querySelectorAll('.layout > .runs, .layout > .side');
  if (!enlarged) {
    if (document.documentElement.scrollWidth > innerWidth)
      problems.push(`the page is ${document.documentElement.scrollWidth} px wide in a ${innerWidth} px window`);
    const panels = [...document.querySelectorAll(
      'header.top, .layout > .runs, .layout > .procedure-panel, .layout > .side')].filter(shown);
    const bottom = document.documentElement.scrollHeight - innerHeight;
    for (let y = 0; ; y = Math.min(bottom, y + innerHeight / 3)) {
      scrollTo(0, y);
      pairs(panels, `scrolled ${Math.round(y)} px`);
      if (y >= bottom) break;
    }
    scrollTo(0, 0);
  }
  const view = document.querySelector('#spatial-view');
  if (view && shown(view)) {
    const overlays = [...view.querySelectorAll(
      '.ct-spatial-age, .ct-spatial-status, .ct-spatial-camera, .ct-spatial-bar')].filter(shown);
    pairs(overlays, 'in the 3D view');
    for (const e of [...overlays, ...view.querySelectorAll('.ct-spatial-bar *')].filter(shown))
      if (!within(rect(e), rect(view))) problems.push(`${name(e)} runs past the 3D view's edge`);
  }
  // the runs list's entries too: they carry the approval requests of every run
  const controls = [...(enlarged ? view : document).querySelectorAll(
    (enlarged ? '' : 'header.top :is(button, a[href]), #run-list li, ')
    + ':is(#main-view, .ct-spatial) :is(button, input, select, textarea, a[href])')].filter(shown);
  for (const control of controls) {
    (control.closest('.ct-spatial') ?? control).scrollIntoView({block: 'center', inline: 'nearest'});
    const r = control.getBoundingClientRect();
    const x = r.left + r.width / 2, y = r.top + r.height / 2;
    const hit = x >= 0 && y >= 0 && x < innerWidth && y < innerHeight ? document.elementFromPoint(x, y) : null;
    if (!hit || !control.contains(hit))
      problems.push(`${name(control)} cannot be brought into view: `
                    + (hit ? `${name(hit)} lies over it` : 'it stays off the window'));
  }
  scrollTo(0, 0);
  for (const e of innerScrolls()) e.scrollTop = 0;
  return problems;
}"""


@pytest.fixture(scope="module")
def iva() -> Iterator[Habitat]:
    habitat = Habitat.open("iva")
    yield habitat
    habitat.close()


def spatial_feed(iva: Habitat) -> list[dict[str, Any]]:
    """What the ground server would push to a browser for an IVA run with the filter's template
    planned: the scene, the template, its plan, the arm's state (stamped ahead of this clock, so
    the age reads at its longest), a camera picture and a perception result that did not register."""
    running = RunningTemplate.add(iva, "cdra_filter", "ur10", object_name="cdra_filter", frame="cabinet/slot")
    start = [float(v) for v in iva.mapping["robot"]["initial_positions"]]
    picture = base64.b64encode((REPO / "docs" / "images" / "scene_iva.png").read_bytes()).decode()
    not_located = {
        "object": "cdra_filter",
        "camera": "rack_camera",
        "success": False,
        "message": NOT_LOCATED,
        "header": {"stamp": {"sec": 1, "nanosec": 0}, "frame_id": ""},
    }
    updates = [
        running.update("grasp_and_pull"),
        running.plan("grasp_and_pull", start),
        {"kind": "joints", "stamp": time.time() + 3600, "positions": dict(zip(iva.arm_joints, start, strict=True))},
        {"kind": "camera", "url": f"data:image/png;base64,{picture}"},
        located_update(not_located, {}),
    ]
    return [{"type": "scene", "document": iva.document()}] + [{"type": "update", "update": u} for u in updates]


def wait_view(page: Page, condition: str) -> None:
    """Until ``condition`` (JS over ``v``, the view's inspect()) holds."""
    page.wait_for_function(
        f"(() => {{ const s = window.caretakerSpatial; const v = s && s.inspect(); return v && ({condition}); }})()"
    )


def layout_problems(page: Page, width: int, *, enlarged: bool = False) -> list[str]:
    """What lies over what at this width (:data:`MEASURE`), each problem with the width."""
    where = f"{width} px, enlarged" if enlarged else f"{width} px"
    return [f"{where}: {problem}" for problem in page.evaluate(MEASURE, enlarged)]


@pytest.mark.parametrize("server", ["sqlite"], indirect=True)
def test_no_panel_or_overlay_lies_over_another_at_any_width(
    webgl_browser: Browser, server: WebServer, iva: Habitat
) -> None:
    feed = spatial_feed(iva)
    sockets: list[WebSocketRoute] = []

    def play_feed(socket: WebSocketRoute) -> None:
        sockets.append(socket)
        for message in feed:
            socket.send(json.dumps(message))

    with signed_in_pages(webgl_browser, sign_in_on) as open_as:
        page = open_as(server.url, "alice")
        page.route_web_socket(re.compile(r"/ws/runs/[^/]+/spatial$"), play_feed)
        start_run(page, IVA, "manual")  # it waits at 1.1 for the operator: nothing moves while it is measured
        try:
            problems = measure_every_width(page, sockets)
        finally:  # the run ends whatever was found: the suite's server runs other tests on this robot
            page.set_viewport_size({"width": 1500, "height": 1000})
            stop_run(page, "layout measured")
    assert not problems, "\n".join(problems)


def measure_every_width(page: Page, sockets: list[WebSocketRoute]) -> list[str]:
    """The layout's problems at each window, with the 3D view, enlarged, and without it."""
    expect(page.locator("#hold")).to_contain_text("1.1")  # the banner is up
    wait_view(page, "v.settled && v.camera_url && Object.keys(v.templates).length > 0")
    expect(page.locator("#spatial-view .ct-spatial-status")).to_contain_text(NOT_LOCATED)
    expect(page.locator("#spatial-view .ct-spatial-plan")).to_be_visible()
    problems: list[str] = []
    for width, height in WINDOWS:
        page.set_viewport_size({"width": width, "height": height})
        wait_view(page, "v.settled")
        problems += layout_problems(page, width)
        screenshot(page, f"console-layout-{width}.png")
        page.click("#spatial-view [data-action=enlarge]")
        wait_view(page, "v.enlarged && v.settled")
        problems += layout_problems(page, width, enlarged=True)
        if width == 1024:
            screenshot(page, "console-layout-enlarged.png")
        page.keyboard.press("Escape")
        wait_view(page, "!v.enlarged && v.settled")

    # the same run without a 3D view (a robot side without one): the layout without its column
    sockets[-1].send(json.dumps({"type": "none"}))
    expect(page.locator("#spatial-panel")).to_be_hidden()
    for width, height in WINDOWS:
        page.set_viewport_size({"width": width, "height": height})
        problems += [f"{p} (no 3D view)" for p in layout_problems(page, width)]
    return problems
