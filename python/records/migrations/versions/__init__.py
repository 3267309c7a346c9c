"""Revisions of the audit-log schema, oldest first (0001 is the schema from before migrations)."""
