# Two commands do everything on a fresh machine:
#   make run    - the TUI on the bundled sample mission
#   make test   - lint, format check, type check, then the whole test suite (what CI runs)
# Each creates the virtual environment it needs (.venv) on first use.
# For the developer loop: make check (lint + types), make quick (the tests not marked slow),
# make fix (ruff's safe fixes and formatting).

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SAMPLE ?= sample_data/missions/hidden-tam-contamination

# Lint, format and type checks cover these
CODE   := gcs_core gcs_tui tests benchmarks

.PHONY: run test quick check fix bench clean-venv browser constraints shared-note

# Every package at the version in constraints.txt (the versions the SVG snapshots and the
# documented numbers were made with); pyproject.toml states only the compatible ranges.
$(STAMP): pyproject.toml constraints.txt
	@echo "make: first use: creating $(VENV) and installing GCS with its dependencies"
	@echo "      (numpy, scipy, h5py, numba, textual, pytest, ruff, mypy ...; about a minute, once)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e '.[fast,test,dev,bench]'
	@echo "make: compiling the numerical kernels once, so the first fit takes seconds (gcs warmup, about 30 s)"
	$(BIN)/gcs warmup
	touch $(STAMP)
	@echo "make: $(VENV) is ready"

run: $(STAMP)
	@$(BIN)/python -c "from gcs_core.warmup import cold_start; raise SystemExit(cold_start())" || \
	  { echo "make: compiling the numerical kernels once (gcs warmup, about 30 s)"; $(BIN)/gcs warmup; }
	$(BIN)/gcs tui $(SAMPLE)

# The exported-plot test opens the HTML in a real headless browser: install Chromium from
# the distribution when it is missing and apt-get is there (the test skips, saying why,
# where it cannot be installed).
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || \
	  { if command -v apt-get >/dev/null 2>&1; then \
	      echo "make: installing chromium (apt-get) for the exported-plot test"; \
	      SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	      $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium \
	        >/dev/null || echo "make: chromium not installed; the browser test will be skipped"; \
	    else echo "make: no apt-get; the browser test will be skipped"; fi; }

# Lint (ruff check), formatting (ruff format --check) and types (mypy, files from pyproject.toml).
check: $(STAMP)
	$(BIN)/python -m ruff check $(CODE)
	$(BIN)/python -m ruff format --check $(CODE)
	$(BIN)/python -m mypy

# ruff's safe fixes (import order, modern spellings, stale noqa) and the formatter.
fix: $(STAMP)
	$(BIN)/python -m ruff check --fix $(CODE)
	$(BIN)/python -m ruff format $(CODE)

# NO_COLOR breaks the SVG snapshots, so it is removed from the environment here. -rs lists
# why each test was skipped: the conformance checks run only with the independent example
# missions in ../shared/examples beside the checkout.
test: check browser shared-note
	env -u NO_COLOR OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -rs -n 2 $(PYTEST_ARGS)

# The developer loop: every test not marked slow, no checks first.
quick: $(STAMP) shared-note
	env -u NO_COLOR OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -rs -n 2 -m "not slow" $(PYTEST_ARGS)

shared-note:
	@test -d ../shared/examples || echo "make: ../shared/examples is not beside this checkout: the conformance checks will be skipped (reasons at the end)"

bench: $(STAMP)
	for f in benchmarks/*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

clean-venv:
	rm -rf $(VENV)

# After a deliberate upgrade in .venv: record the versions (then regenerate snapshots, re-run make bench).
constraints: $(STAMP)
	{ echo "# Exact versions for make's installs (pip install -c constraints.txt); pyproject.toml has the ranges."; \
	  echo "# Regenerate with 'make constraints' after a deliberate upgrade."; \
	  $(BIN)/python -m pip freeze --exclude-editable | grep -v '^gcs=='; } > constraints.txt
