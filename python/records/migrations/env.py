"""Alembic environment: migrate the connection :func:`records.audit_schema.ensure_schema` hands over."""

from __future__ import annotations

from alembic import context

from records.audit_schema import VERSION_TABLE

connection = context.config.attributes["connection"]
context.configure(
    connection=connection, version_table=VERSION_TABLE, render_as_batch=connection.dialect.name == "sqlite"
)
with context.begin_transaction():  # joins the caller's transaction: the whole upgrade commits or none of it
    context.run_migrations()
