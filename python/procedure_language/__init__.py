"""procedure_language: the files operators and engineers write, read and checked before anything runs.

Procedures (PRIDE-like XML), SysReps (the commands and telemetry a system offers) and bindings
(which plugins serve which SysRep, over which bridge) are read here into checked records, and a
procedure's meaning is checked against the SysReps (``caretaker lint``). Nothing here runs a
procedure or reaches a robot: the executive (:mod:`pride`) runs what this package has checked,
and the Java PAX plugins read the same SysRep and binding files with the same checks and
messages (tests/fixtures/sysrep, tests/fixtures/bindings).

Modules, by concept:

- :mod:`procedure_language.sysrep` — SysRep files; :mod:`procedure_language.binding` — binding files.
- :mod:`procedure_language.xml_reader` — a procedure file from outside into an XML tree (no DTD,
  no entities); :mod:`procedure_language.schema` its check against ``procedures/schema/procedure.xsd``.
- :mod:`procedure_language.model`, :mod:`procedure_language.parser` — procedure XML into numbered
  steps and instructions.
- :mod:`procedure_language.lint` — meaning checks against SysReps; a run's procedure tree checked
  once (:class:`procedure_language.lint.CheckedProcedure`).
- :mod:`procedure_language.diagnostics` — a problem at a file and line, and the error that lists them.
"""
