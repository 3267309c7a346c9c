# Caretaker: `make demo` runs the main job, `make test` runs every test. Both set up what they
# need first (tools/setup.sh: Debian packages, .venv, ROS interfaces, Java build, Node clients).
VENV := .venv
PYTEST := $(VENV)/bin/pytest

.PHONY: setup lint test test-java test-python demo docs bench clean

setup:
	@./tools/setup.sh

# Runs a command with its output held until it ends: beside the test suite's live output, lint's
# and JUnit's each come as one block.
held = out=$$( { $(1); } 2>&1 ); status=$$?; [ -z "$$out" ] || printf '%s\n' "$$out"; exit $$status

# ruff and mypy on the project's own code (configured in pyproject.toml). mypy keeps its cache in
# the user's cache, which every checkout shares: it checks a module again only if its contents
# changed (by hash, whatever the file's time), so a fresh clone's check takes about 1 s of CPU
# instead of 30.
CACHE := $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/caretaker
lint: setup
	@$(call held,$(VENV)/bin/ruff check && MYPY_CACHE_DIR=$(CACHE)/mypy $(VENV)/bin/mypy)

# Lint, JUnit and pytest side by side: the whole command lasts as long as its longest test file
# (the 10-minute onboard outage) plus set-up, instead of their sum; a failure in any fails it.
test: setup
	@$(MAKE) --no-print-directory -j 3 lint test-java test-python

test-java: setup
	@if [ -f pom.xml ]; then $(call held,mvn -q test); fi

# Eight workers on the CI machine's 2 cores: the suite waits more than it computes (a link's light
# time, a ten-minute outage, processes and browsers starting), so more files run at once than there
# are cores, but no more of the files that compute than the cores can carry. The scheduler (tests/
# support/file_schedule.py) hands out whole files, the longest first, within a budget of cores
# measured per file (tests/file_costs.json), holds a worker when nothing left fits, and queues no
# file behind a long one. A file per worker at a time, so module fixtures (a robot stack, a
# browser) are built once.
# PYTHONDONTWRITEBYTECODE, set on these machines, would have every worker compile and rewrite the
# asserts of every test module it collects (about 6 s of CPU each): the tests' bytecode is written
# (into __pycache__, ignored by git) by one collection before the workers start; its errors, if
# any, are reported by the run itself.
PYTEST_WORKERS ?= 8
test-python: setup
	@PYTHONDONTWRITEBYTECODE= $(PYTEST) --collect-only -q tests > /dev/null 2>&1 || true
	PYTHONDONTWRITEBYTECODE= $(PYTEST) -n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder --durations=25 tests

demo: setup
	$(VENV)/bin/caretaker demo deployments/iva.yaml

# The README's screenshots: the browser tests that take them, writing into docs/images (a plain
# test run writes them to a temporary folder and never touches tracked files).
docs: setup
	CARETAKER_SCREENSHOTS=$(CURDIR)/docs/images $(PYTEST) tests/web/test_operator_view.py \
		tests/web/test_flight_controls.py tests/web/test_authoring.py tests/web/test_web_on_real_stack.py tests/web/test_spatial_on_real_stack.py \
		tests/web/test_console_layout.py \
		tests/web/test_console_follows_the_run.py::test_monitors_and_values_show_their_limits_in_colour_and_in_words

# Every benchmark; the harnesses that run another command (cpu_load.py, cpu_by_part.py,
# suite_profile.py, schedule_replay.py, start_cpu.py) are tools for any of them, not benchmarks themselves; fleet_ground.py is part of fleet.py.
BENCHMARKS := $(filter-out bench/cpu_load.py bench/cpu_by_part.py bench/suite_profile.py bench/schedule_replay.py bench/start_cpu.py bench/fleet_ground.py,$(wildcard bench/*.py))
bench: setup
	@for b in $(BENCHMARKS); do echo "== $$b"; $(VENV)/bin/python $$b || exit 1; done

clean:
	rm -rf build java/pax-plugins/target
