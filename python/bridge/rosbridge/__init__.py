"""rosbridge protocol v2 server on rclpy (``caretaker bridge``); see docs/rosbridge.md."""
