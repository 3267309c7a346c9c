"""Alembic migrations of the audit log, run by :func:`records.audit_schema.ensure_schema` (no alembic.ini).

A new revision is a file in ``versions/`` with the next number, ``down_revision`` the previous
one, and an ``upgrade()`` that works on SQLite (batch mode) and PostgreSQL. Audit records are
never rewritten except by a migration that must, and none is downgraded: restore a backup.
"""
