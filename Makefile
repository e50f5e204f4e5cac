# The README's commands. Each target installs what it needs into .venv itself.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEMO_OUT := out/demo
SEED ?= 0

.PHONY: demo test bench schemas mutants install clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/sagebench demo --seed $(SEED) --out $(DEMO_OUT)

test: $(STAMP)
	$(BIN)/python -m pytest -n 2

bench: $(STAMP)
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	$(BIN)/python -m benchmarks

# named breaks applied to a temporary copy; fails when a test no longer catches one (about 75 s)
mutants: $(STAMP)
	$(BIN)/python tools/mutants.py

schemas: $(STAMP)
	$(BIN)/sagebench schemas --out schemas

clean:
	rm -rf out .pytest_cache
