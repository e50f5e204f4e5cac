# The README's commands. Each target installs what it needs into .venv itself.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# exact versions everything was tested with; `make lock` regenerates it after a dependency change
LOCK := constraints.txt
DEMO_OUT := out/demo
SEED ?= 0

.PHONY: demo test test-slow explore bench schemas docs mutants lock install clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip

$(STAMP): pyproject.toml $(LOCK) | $(BIN)/python
	$(BIN)/python -m pip install -q -c $(LOCK) -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/sagebench demo --seed $(SEED) --out $(DEMO_OUT)

# CI's profile: the same hypothesis examples on every run (tests/profiles.py). The few end-to-end tests on full demo
# apartments and the two-node Ray cluster (marked slow) are left to test-slow; CI (.ci/run) runs both
test: $(STAMP)
	$(BIN)/python -m pytest -n 2 --hypothesis-profile=ci -m "not slow"

test-slow: $(STAMP)
	$(BIN)/python -m pytest -n 2 --hypothesis-profile=ci -m slow

# before a release: the property tests alone, ten times the examples, from a fresh seed (printed; pass
# EXPLORE_SEED=N to replay one); a failure found becomes an explicit @example on its test
# drawn once (`:=`): a recursive `?=` drew one seed for the echo and another for pytest
ifeq ($(origin EXPLORE_SEED), undefined)
EXPLORE_SEED := $(shell $(PY) -c "import secrets; print(secrets.randbelow(2**32))")
endif
explore: $(STAMP)
	@echo "make explore: hypothesis seed $(EXPLORE_SEED)"
	$(BIN)/python -m pytest -n 2 -m hypothesis --hypothesis-profile=explore --hypothesis-seed=$(EXPLORE_SEED)

bench: $(STAMP)
	$(BIN)/python -m pip install -q -c $(LOCK) -e '.[test,bench]'
	$(BIN)/python -m benchmarks

# named breaks applied to a temporary copy; fails when a test no longer catches one (about 100 s)
mutants: $(STAMP)
	$(BIN)/python tools/mutants.py

# pins what is installed now (keeping installed versions, adding new dependencies); run the tests, then commit it
lock: | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[test,bench]'
	{ echo "# Exact versions sagebench is tested with: make test / make demo / CI install with -c $(LOCK)."; \
	  echo "# Regenerate with make lock after changing dependencies in pyproject.toml."; \
	  $(BIN)/python -m pip freeze --exclude-editable; } > $(LOCK).tmp
	mv $(LOCK).tmp $(LOCK)
	touch $(STAMP)

schemas: $(STAMP)
	$(BIN)/sagebench schemas --out schemas

# docs/cli.md from every command's --help (tests/test_cli_docs.py fails when it is stale)
docs: $(STAMP)
	$(BIN)/python tools/cli_docs.py

clean:
	rm -rf out .pytest_cache
