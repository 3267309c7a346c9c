# Caretaker: `make demo` runs the main job, `make test` runs every test. Both set up what they
# need first (tools/setup.sh: Debian packages, .venv, ROS interfaces, Java build, Node clients).
VENV := .venv
PYTEST := $(VENV)/bin/pytest

.PHONY: setup test test-java test-python demo bench clean

setup:
	@./tools/setup.sh

test: setup test-java test-python

test-java:
	@if [ -f pom.xml ]; then mvn -q test; fi

test-python:
	$(PYTEST) tests

demo: setup
	$(VENV)/bin/caretaker demo deployments/iva.yaml

bench: setup
	@for b in bench/*.py; do echo "== $$b"; $(VENV)/bin/python $$b || exit 1; done

clean:
	rm -rf build java/pax-plugins/target
