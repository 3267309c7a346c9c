"""pride: PRIDE-like electronic procedures and PAX, the executive that runs them with operators.

Modules, by concept:

- :mod:`pride.sysrep` — SysRep files: the commands and telemetry procedures may name.
- :mod:`pride.model`, :mod:`pride.parser`, :mod:`pride.schema` — procedure XML
  (``procedures/schema/procedure.xsd``) into numbered steps and instructions.
- :mod:`pride.lint` — meaning checks against SysReps (``caretaker lint``).
- :mod:`pride.executive` — PAX: manual and autonomous runs, operator actions, observers;
  :mod:`pride.states` its observable states, :mod:`pride.automation` the part that acts on systems.
- :mod:`pride.systems` — the PAX host shape the executive talks to (no ROS, no JVM here).
- :mod:`pride.events`, :mod:`pride.audit_log` — every action, append-only, committed per action;
  :mod:`pride.audit_chain` its hash chain, :mod:`pride.audit_schema` and :mod:`pride.migrations`
  its tables and their Alembic migrations.
- :mod:`pride.report` — after-action reports; :mod:`pride.terminal`, :mod:`pride.cli` — the CLI.
"""
