# Convenience targets; each is the README command of the same name.
PY := .venv/bin/python

# The simulator alone (README command 1): jax, flax, numpy, pillow.
.venv/installed: pyproject.toml
	python3 -m venv .venv
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $@

# Everything the tests need (README command 2, what CI runs).
.venv/installed-dev: .venv/installed
	$(PY) -m pip install --quiet -e ".[dev]"
	touch $@

setup: .venv/installed-dev
demo: .venv/installed
	$(PY) -m raidjax.calibrate --games 1000
test: .venv/installed-dev
	$(PY) -m pytest
bench: .venv/installed
	$(PY) benchmarks/env_throughput.py

.PHONY: setup demo test bench
