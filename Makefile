# Caretaker: `make demo` runs the main job, `make test` runs every test. Both set up what they
# need first (tools/setup.sh: Debian packages, .venv, ROS interfaces, Java build, Node clients).
VENV := .venv
PYTEST := $(VENV)/bin/pytest

.PHONY: setup lint test test-java test-python demo docs bench clean

setup:
	@./tools/setup.sh

# ruff and mypy on the project's own code (configured in pyproject.toml); `make test` runs it first.
lint: setup
	$(VENV)/bin/ruff check
	$(VENV)/bin/mypy

test: setup lint test-java test-python

test-java:
	@if [ -f pom.xml ]; then mvn -q test; fi

# Three workers on the CI machine's 2 cores: the suite waits more than it computes (links,
# processes, browsers: about two thirds of both cores busy with three; four starve the robot
# stacks). A test file per worker so module fixtures (a robot stack, a browser) are built once;
# the longest files first (tests/conftest.py), so the 12-minute onboard outage test, which mostly
# waits out its outage, runs beside everything else instead of after it.
PYTEST_WORKERS ?= 3
test-python:
	$(PYTEST) -n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder --durations=25 tests

demo: setup
	$(VENV)/bin/caretaker demo deployments/iva.yaml

# The README's screenshots: the browser tests that take them, writing into docs/images (a plain
# test run writes them to a temporary folder and never touches tracked files).
docs: setup
	CARETAKER_SCREENSHOTS=$(CURDIR)/docs/images $(PYTEST) tests/web/test_operator_view.py \
		tests/web/test_flight_controls.py tests/web/test_authoring.py tests/web/test_web_on_real_stack.py tests/web/test_spatial_on_real_stack.py

bench: setup
	@for b in bench/*.py; do echo "== $$b"; $(VENV)/bin/python $$b || exit 1; done

clean:
	rm -rf build java/pax-plugins/target
