"""The gripper's ROS interface on the simulation node: /gripper/set, what it holds and how.

``gripper/grasp`` says how the gripper holds, as a real gripper's object status does (Robotiq's
gOBJ): ``moving``, ``holding`` (closed on an object), ``open``, ``halted`` (stopped short of its
pose by a halt, holding nothing), or ``empty`` (closed on nothing: a grasp that missed, or an
object that slipped out). A procedure's monitor watches it while the
arm carries a filter (procedures/iva_cdra_filter_replacement.xml). ``sim/check/slip`` lets a
test make the held filter slip out of the closed fingers, the fault that monitor is for.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

from caretaker_sim_msgs.srv import SetGripper
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import String
from std_srvs.srv import Trigger

from ros_process.delay_hooks import pause
from sim.halt_order import HaltOrder
from sim.simulation import Simulation

__all__ = ["GripperInterface"]

LOG = logging.getLogger(__name__)


class GripperInterface:
    """The gripper's services and topics, served by ``node`` for ``sim`` (which has a gripper)."""

    def __init__(
        self,
        node: Node,
        sim: Simulation,
        order: HaltOrder,
        wait: Callable[[threading.Event, float], bool],
        *,
        latched: QoSProfile,
        services: QoSProfile,
        group: CallbackGroup,
    ) -> None:
        self._sim, self._order, self._wait = sim, order, wait
        self.held_pub = node.create_publisher(String, "gripper/held_object", latched)
        self.grasp_pub = node.create_publisher(String, "gripper/grasp", latched)
        self.set_srv = node.create_service(
            SetGripper, "gripper/set", self.set_callback, qos_profile=services, callback_group=group
        )
        self.slip_srv = node.create_service(
            Trigger, "sim/check/slip", self.slip_callback, qos_profile=services, callback_group=group
        )

    def publish(self, held: str, grasp: str) -> None:
        self.held_pub.publish(String(data=held))
        self.grasp_pub.publish(String(data=grasp))

    def set_callback(self, request: SetGripper.Request, response: SetGripper.Response) -> SetGripper.Response:
        sim = self._sim
        assert sim.gripper is not None
        with sim.world_lock:
            ticket = self._order.ticket(request.issued)
        pause("sim.gripper")
        with sim.world_lock:
            halted = self._order.refusal(ticket)  # crossed a halt on its way: the fingers must not move
            motion = sim.gripper.start(request.pose) if halted is None else None
        if motion is None:
            LOG.warning("gripper refused: %s", halted)
            response.success, response.message = False, halted
        elif not self._wait(motion.done, 2.0):
            response.success, response.message = False, f"gripper did not reach {request.pose!r} in time"
        else:
            response.success, response.message, response.held_object = (
                motion.success,
                motion.message,
                motion.held_object,
            )
        return response

    def slip_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """A test's fault: the held filter slips out; the fingers stay where they are."""
        with self._sim.world_lock:
            if self._sim.filters.held() is None:
                response.success, response.message = False, "nothing is held: nothing can slip"
                return response
            response.success, response.message = True, f"slipped: {self._sim.filters.release()}"
        LOG.warning("gripper test: %s", response.message)
        return response
