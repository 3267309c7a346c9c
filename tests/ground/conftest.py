"""The ground segment's tests drive the console as the web suite does (support.operator_page)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import expect

from records.audit_log import AuditLog
from support.browser import TIMEOUT_MS
from support.web_server import GroundDatabase, new_ground_database

expect.set_options(timeout=TIMEOUT_MS)


@pytest.fixture(params=["sqlite", "postgresql"])
def audit(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[AuditLog]:
    """An audit log on a SQLite file, then on the session's PostgreSQL."""
    postgres = request.getfixturevalue("postgres") if request.param == "postgresql" else None
    database: GroundDatabase = new_ground_database(request.param, tmp_path, postgres)
    log = AuditLog(database.url)
    yield log
    log.close()
