"""records: the ground's records, in SQLAlchemy and Alembic, apart from the executive that writes them.

The executive (:mod:`pride`) sees only plain types and protocols (:class:`pride.events.Journal`,
:class:`pride.run_control.ControlStore`, :class:`pride.run_version.RunVersion`); what stores them
is here, so an executive imports no database library (tests/foundation/test_executive_imports.py)
and never this package (tests/foundation/test_package_graph.py). The console and the CLI open
them on the ground database; the onboard executive keeps its habitat chain in the same audit log
on SQLite.

Modules, by concept:

- :mod:`records.audit_log` — every action of every run, append-only, committed per action;
  :mod:`records.audit_chain` its hash chain, :mod:`records.audit_schema` and
  :mod:`records.migrations` its tables and their Alembic migrations.
- :mod:`records.releases` — released procedure versions and whether a version may run.
- :mod:`records.robot_control` — which run controls each robot.
- :mod:`records.onboard_handoffs` — onboard runs handed to a supervising ground process.
- :mod:`records.console_tables` — the consoles' own tables (accounts, run hosts, camera frames,
  forwarded actions), defined once for the console and the migration that creates them.
"""
