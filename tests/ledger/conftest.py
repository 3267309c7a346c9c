"""Fixtures of the ledger suite: a counting ROS peer and an rclpy client of the ledger."""

from .ledger_support import client, peer

__all__ = ["client", "peer"]
