"""Tests of the rosbridge v2 server (a package, so its fixtures can be package-scoped)."""
