"""The ground segment's shared state: what several consoles, runners and agents on one database agree on.

Every console on one ground database sees every run live and can act on any of them, without
talking to the other consoles: the database is the only meeting point (docs/ground-segment.md,
"Several consoles").

- :mod:`ground.change_feed`: changes as they happen (PostgreSQL LISTEN/NOTIFY; SQLite polled).
- :mod:`ground.run_hosts`: which process runs each live run's executive, under a lease it
  renews, and the view of the run it publishes for the others.
- :mod:`ground.action_requests`: an operator action on a run hosted elsewhere, forwarded to
  its host through the database and answered the same way.
"""
