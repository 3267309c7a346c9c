"""The PAX tests' fixtures: one robot stack per module (``pax_stack``)."""

from pax_stack import ros_env_module, stack  # noqa: F401 (pytest registers a conftest's fixtures by name)
