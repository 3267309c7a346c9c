"""The 3D view's frame rate and update-to-frame latency in every drawing mode, side by side.

Usage: .venv/bin/python bench/spatial_frame_rate.py

Runs tests/web/test_spatial_view.py's frame-rate measurement (headless Chromium, WebGL on
SwiftShader, joint updates streamed into one page) with every mode: at 50 updates/s every frame
at full resolution, every frame with adaptive resolution, and on demand with it; at 10/s on demand
drawn as each state arrives and interpolated. The test suite measures only the console's way.
Prints the figures the test reports (docs/benchmarks.md holds them); exit status 1 if it failed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TEST = "tests/web/test_spatial_view.py"


def main() -> int:
    done = subprocess.run(
        [str(REPO / ".venv/bin/pytest"), TEST, "-s", "-q", "-k", "frame_rate"],
        cwd=REPO,
        env={**os.environ, "CARETAKER_FRAME_RATE_MODES": "all"},
        capture_output=True,
        text=True,
        timeout=900,
    )
    report = done.stdout[done.stdout.find("spatial view (") :]
    print(report.split("\n\n")[0] if done.returncode == 0 else done.stdout[-3000:])
    return 0 if done.returncode == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
