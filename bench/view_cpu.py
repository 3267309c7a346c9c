"""What one 3D view costs Chromium in CPU: idle, and while a 10/s joint stream moves the arm.

    .venv/bin/python bench/view_cpu.py [--seconds 10] [--caps inf,30,20,15]

Opens the view alone (tests/web's spatial test page, the shipped IVA scene) in headless Chromium
with WebGL on SwiftShader, as the browser tests do, at 1000x700; then, one after the other in the
same page: idle; joint states at 10/s drawn moving between them with each frame cap of
``--caps`` (``inf``: one frame every animation frame that has news, the view before the cap);
the same states drawn as they come; idle again. For each, the CPU of every Chromium process
(browser, renderer, GPU process: /proc) over ``--seconds`` as a share of one core, and the frames
drawn a second. Side by side in one run, so the ratios hold on a noisy machine.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import psutil

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO / "tests"), str(REPO / "tests" / "web")]

from playwright.sync_api import Page, sync_playwright  # noqa: E402

# tests/web's own helpers, which the type check does not cover
from spatial_data import Habitat  # type: ignore[import-not-found]  # noqa: E402
from spatial_site import serve_site  # type: ignore[import-not-found]  # noqa: E402

from support.browser import CHROMIUM, HEADLESS_ARGS, WEBGL_ARGS  # noqa: E402

SEND = "(v) => window.caretakerSpatial.apply({kind: 'joints', stamp: 0, positions: {wrist_3_joint: v, elbow_joint: v}})"


def chromium_cpu(browser: psutil.Process) -> float:
    """CPU seconds of ``browser`` and every process under it."""
    total = 0.0
    for process in [browser, *browser.children(recursive=True)]:
        try:
            times = process.cpu_times()
        except psutil.Error:
            continue
        total += times.user + times.system
    return total


@contextmanager
def view_page() -> Iterator[tuple[Page, psutil.Process]]:
    habitat = Habitat.open("iva")
    try:
        with serve_site() as site, sync_playwright() as driver:
            browser = driver.chromium.launch(executable_path=CHROMIUM, args=[*HEADLESS_ARGS, *WEBGL_ARGS])
            chromium = next(c for c in psutil.Process().children(recursive=True) if "chrom" in c.name())
            page = browser.new_context(viewport={"width": 1000, "height": 700}).new_page()
            page.goto(site.url + "/")
            page.evaluate(
                "([url, canAct]) => window.startView(url, canAct)",
                [site.put_json("/scene.json", habitat.document()), True],
            )
            page.wait_for_function(
                "window.caretakerSpatial && window.caretakerSpatial.inspect().settled", timeout=60_000
            )
            yield page, chromium
            browser.close()
    finally:
        habitat.close()


def measure(page: Page, chromium: psutil.Process, seconds: float, stream: bool) -> tuple[float, float]:
    """(share of a core, frames/s) over ``seconds``, sending joint states at 10/s if ``stream``."""
    frames = page.evaluate("window.caretakerSpatial.inspect().frames")
    cpu = chromium_cpu(chromium)
    start = time.monotonic()
    k = 0
    while (elapsed := time.monotonic() - start) < seconds:
        if stream:
            page.evaluate(SEND, math.sin(k / 20))
            k += 1
        time.sleep(max(0.0, 0.1 * k - elapsed) if stream else 0.1)
    elapsed = time.monotonic() - start
    drawn = page.evaluate("window.caretakerSpatial.inspect().frames") - frames
    return (chromium_cpu(chromium) - cpu) / elapsed, drawn / elapsed


def configure(page: Page, interpolate: bool, cap: float) -> None:
    fps = "Infinity" if math.isinf(cap) else f"{cap:g}"
    page.evaluate(
        f"(i) => {{ const v = window.caretakerSpatial; v.setJointInterpolation(i); v.setMaxFrameRate({fps}); }}",
        interpolate,
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--caps", default="inf,30,20,15", help="frame caps to compare, comma-separated (inf: none)")
    args = parser.parse_args()
    caps = [float(c) for c in args.caps.split(",")]
    rows = []
    with view_page() as (page, chromium):
        rows.append(("idle", *measure(page, chromium, args.seconds, stream=False)))
        for cap in caps:
            configure(page, interpolate=True, cap=cap)
            rows.append((f"10/s, interpolated, cap {cap:g}", *measure(page, chromium, args.seconds, stream=True)))
        configure(page, interpolate=False, cap=20)
        rows.append(("10/s, drawn as they come, cap 20", *measure(page, chromium, args.seconds, stream=True)))
        rows.append(("idle again", *measure(page, chromium, args.seconds, stream=False)))
    load = psutil.getloadavg()[0]
    cores = psutil.cpu_count()
    print(f"3D view, 1000x700, SwiftShader; {args.seconds:g} s each; load average {load:.1f} on {cores} cores")
    print(f"{'what':36} {'Chromium CPU':>14} {'frames/s':>9}")
    for what, share, fps in rows:
        print(f"{what:36} {share:13.1%} {fps:9.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
