"""Shared test support: processes, ROS environment."""
