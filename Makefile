# Quick start: `make demo` and `make test` each work on a fresh clone of a fresh machine.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench clean

$(PY):
	$(PYTHON) -m venv $(VENV)

# Reinstall whenever the package metadata changes.
$(STAMP): pyproject.toml | $(PY)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/robocup-mcl demo walk --rrd recordings/walk.rrd

test: $(STAMP)
	$(PY) -m pytest

# The benchmark also needs the `bench` extra (filterpy and particles to compare with, matplotlib to plot).
BENCH_STAMP := $(VENV)/.installed-bench
$(BENCH_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e '.[test,bench]'
	touch $(BENCH_STAMP)

bench: $(BENCH_STAMP)
	$(VENV)/bin/robocup-mcl bench --save recordings/bench.json --plot recordings/bench.png

clean:
	rm -rf $(VENV) recordings .pytest_cache .hypothesis
