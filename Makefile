# Convenience targets; each is the README command of the same name.
PY := .venv/bin/python

.venv/installed: pyproject.toml
	python3 -m venv .venv
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $@

setup: .venv/installed
demo: setup
	$(PY) -m raidjax.calibrate --games 1000
test: setup
	$(PY) -m pytest
bench: setup
	$(PY) benchmarks/env_throughput.py

.PHONY: setup demo test bench
