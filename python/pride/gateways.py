"""Opening the gateway a run talks to: the PAX host for a binding file, or a test's stand-in.

``caretaker run --binding FILE`` and the web view open the real host, :class:`pride.pax_host.PaxHost`.
The environment variable ``PRIDE_GATEWAY=module:factory`` replaces it with another gateway
factory called with the binding path; it exists so a runner can be driven against a gateway a
test controls in a separate, killable process (tests/pride/test_runner.py).
"""

from __future__ import annotations

import importlib
import os
from typing import cast

from pride.systems import SystemGateway

__all__ = ["GATEWAY_ENV", "GatewaySpecError", "open_gateway"]

GATEWAY_ENV = "PRIDE_GATEWAY"


class GatewaySpecError(ValueError):
    """``PRIDE_GATEWAY`` does not name a ``module:factory``; ``spec`` is the value given."""

    def __init__(self, spec: str) -> None:
        super().__init__(f"{GATEWAY_ENV}={spec!r}: expected module:factory")
        self.spec = spec


def open_gateway(binding_path: str, *, rosbridge_url: str | None = None) -> SystemGateway:
    """Open the gateway for a binding file: the PAX host, or the factory named by ``PRIDE_GATEWAY``.

    ``rosbridge_url`` replaces the binding's rosbridge address (a robot served on another port).
    """
    spec = os.environ.get(GATEWAY_ENV)
    if spec:
        module_name, _, factory_name = spec.partition(":")
        if not factory_name:
            raise GatewaySpecError(spec)
        factory = getattr(importlib.import_module(module_name), factory_name)
        return cast(SystemGateway, factory(binding_path))
    from pride.pax_host import PaxHost  # the JVM loads only when a real run needs it

    return PaxHost(binding_path, rosbridge_url=rosbridge_url)
