"""pride: PAX, the executive that runs PRIDE-like electronic procedures with operators.

The procedure side: it never imports rclpy, habitat code, nor the ground's records and their
database libraries (tests/foundation/test_package_graph.py).

Modules, by concept:

- What runs is read and checked by :mod:`procedure_language` (procedures, SysReps, bindings,
  lint), below this package: a run gets a :class:`procedure_language.lint.CheckedProcedure`.
- :mod:`pride.run_setup` — a run's set-up, one way for the console, ``caretaker run`` and the habitat.
- :mod:`pride.executive` — PAX: manual and autonomous runs, operator actions, observers;
  :mod:`pride.run_engine` the machinery it holds (state under one lock, journal first, PAX's
  thread, the supervisor), :mod:`pride.ad_hoc_commands` commands outside the instructions,
  :mod:`pride.run_state` where a run is and how it moves, :mod:`pride.frames` its stack of
  (sub-)procedures, :mod:`pride.replay` rebuilding it from the log, :mod:`pride.states` its
  observable states, :mod:`pride.automation` the part that acts on systems.
- :mod:`pride.systems` — the gateway shape and its result types; :mod:`pride.gateways` opens one;
  :mod:`pride.pax_host` and :mod:`pride.jvm` — the Java PAX plugins hosted through JPype.
- :mod:`pride.events` — every action as an event; a :class:`pride.events.Journal` stores them
  (the audit log, :mod:`records.audit_log`, is not part of this package). What each kind
  records is its payload class in :mod:`pride.event_payloads` (kinds: :mod:`pride.event_kinds`;
  their stored JSON, the same byte for byte: :mod:`pride.event_json`); :mod:`pride.event_words`
  says each event in words.
- :mod:`pride.report` — after-action reports (the commands that use all this, ``caretaker lint``,
  ``run``, ``report`` and ``db``, are :mod:`caretaker.procedure_commands`).
- :mod:`pride.run_control` — a run's control of its robot (its store in the ground database is
  :mod:`records.robot_control`); :mod:`pride.run_version` the version a run runs.

The ground console that serves all this in the browser is its own package, :mod:`console`.
"""
