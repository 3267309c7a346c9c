"""The robot's order of halts and motion requests (sim/halt_order.py), in-process: which requests
a halt keeps from starting. The real processes' orders are tests/at_ros/test_halt_order.py."""

from __future__ import annotations

from builtin_interfaces.msg import Time

from ros_process.command_order import arrived_now, stamp
from sim.halt_order import HaltOrder

NOW = Time()  # zero: when the request or halt arrives


def test_a_request_that_arrived_before_a_halt_never_starts_after_it() -> None:
    order = HaltOrder()
    order.arrived(1, NOW)
    waiting = order.ticket(NOW)
    order.halted("ops: Halt", stamp(arrived_now() - 10.0))  # it reached the robot side a while ago
    assert order.refusal(order.take(1)) == "halted (ops: Halt) before it started: nothing moved"
    assert order.refusal(waiting) is not None
    assert order.refusal(order.ticket(NOW)) is None  # a request after the halt runs


def test_a_request_whose_command_was_issued_before_the_halt_never_starts_however_late_it_comes() -> None:
    order = HaltOrder()
    halt = arrived_now() - 10.0
    order.halted("ops: Halt", stamp(halt))
    assert order.refusal(order.ticket(stamp(halt - 1.0))) == (
        "halted (ops: Halt) before it started (its command was issued before the halt): nothing moved"
    )
    assert order.refusal(order.ticket(stamp(halt + 1.0))) is None  # issued after the halt reached the robot side
