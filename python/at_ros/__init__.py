"""at_ros."""
