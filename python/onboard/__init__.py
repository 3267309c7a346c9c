"""Onboard execution: the habitat runs a procedure itself, the ground supervises across the light time.

- :mod:`onboard.unit`: what goes up (a signed, hashed, expiring procedure unit; an operator's
  keyed action) and how each is checked on arrival.
- :mod:`onboard.habitat_runs`: the habitat's side: takes units, runs each with PAX next to the
  robot, keeps the run's events in its own hash-chained store, takes operators' actions.
- :mod:`onboard.onboard_server`: ``caretaker onboard``, a part of ``caretaker up``: serves
  :mod:`habitat_runs` to the ground through the habitat's rosbridge (it is a rosbridge client on
  the habitat's side of the link; it never opens a port of its own).
- :mod:`onboard.downlink`: the ground's side: uplinks a unit, then copies the run's events into the
  ground's audit log exactly once (same hashes), asking again for whatever it has not heard.

The procedure side's rule holds: nothing here imports rclpy; the AT server, planner and simulator
still never know procedures (docs/deployment.md, "Onboard runs").
"""
