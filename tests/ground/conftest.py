"""The ground segment's tests drive the console as the web suite does (support.operator_page)."""

from __future__ import annotations

from playwright.sync_api import expect

from support.browser import TIMEOUT_MS

expect.set_options(timeout=TIMEOUT_MS)
