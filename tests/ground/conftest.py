"""The ground segment's tests drive the console as the web suite does: its page helpers are shared."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "web"))  # operator_page, web_server

from playwright.sync_api import expect

from support.browser import TIMEOUT_MS

expect.set_options(timeout=TIMEOUT_MS)
