"""pride: PRIDE-like electronic procedures and PAX, the executive that runs them with operators.

The procedure side (ground): it never imports rclpy nor habitat code (tests/foundation/test_package_graph.py).

Modules, by concept:

- :mod:`pride.sysrep` — SysRep files: the commands and telemetry procedures may name;
  :mod:`pride.binding` — binding files: which plugins serve which SysRep, over which bridge.
- :mod:`pride.xml_reader` — a procedure file from outside into an XML tree (no DTD, no entities).
- :mod:`pride.model`, :mod:`pride.parser`, :mod:`pride.schema` — procedure XML
  (``procedures/schema/procedure.xsd``) into numbered steps and instructions.
- :mod:`pride.lint` — meaning checks against SysReps (``caretaker lint``); a run's procedure tree
  checked once (:class:`pride.lint.CheckedProcedure`).
- :mod:`pride.executive` — PAX: manual and autonomous runs, operator actions, observers;
  :mod:`pride.run_engine` the machinery under it (state under one lock, journal first, PAX's
  thread, the supervisor), :mod:`pride.run_state` where a run is and how it moves, :mod:`pride.frames` its stack of
  (sub-)procedures, :mod:`pride.replay` rebuilding it from the log, :mod:`pride.states` its
  observable states, :mod:`pride.automation` the part that acts on systems.
- :mod:`pride.systems` — the gateway shape and its result types; :mod:`pride.gateways` opens one;
  :mod:`pride.pax_host` and :mod:`pride.jvm` — the Java PAX plugins hosted through JPype.
- :mod:`pride.events`, :mod:`pride.audit_log` — every action, append-only, committed per action;
  :mod:`pride.audit_chain` its hash chain, :mod:`pride.audit_schema` and :mod:`pride.migrations`
  its tables and their Alembic migrations.
- :mod:`pride.report` — after-action reports (the commands that use all this, ``caretaker lint``,
  ``run``, ``report`` and ``db``, are :mod:`caretaker.procedure_commands`).
- :mod:`pride.run_control` — a run's control of its robot; :mod:`pride.robot_control` its store
  in the ground database.

The ground console that serves all this in the browser is its own package, :mod:`console`.
"""
