"""The operator web view: watch and run procedures in the browser, on the PAX executive.

``caretaker serve`` (:mod:`pride.web.server`) serves one page (``static/``) and a small API
(:mod:`pride.web.app`). Every change to a run is an executive call made as the signed-in user
(:mod:`pride.web.actions`) and lands in the audit log; everything the page shows is observed
from the executive (:mod:`pride.web.live_run`) or folded from the audit log
(:mod:`pride.web.run_state`), never kept as a second copy of the run.
"""
