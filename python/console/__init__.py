"""The ground console: the operator web view, watching and running procedures in the browser on
the PAX executive, and what several consoles share through one ground database (:mod:`ground`).

Kept apart from :mod:`pride`, whose executive must run where no web server or ground database is
(tests/foundation/test_package_graph.py holds the order: the console imports pride, never the reverse).

``caretaker serve`` (:mod:`console.server`) serves one page (``static/``) and a small API
(:mod:`console.app`). Every change to a run is an executive call made as the signed-in user
(:mod:`console.actions`) and lands in the audit log; everything the page shows is observed
from the executive (:mod:`console.live_run`) or folded from the audit log
(:mod:`console.folded_run`), never kept as a second copy of the run.
"""
