# Two commands do everything on a fresh machine:
#   make run    - the TUI on the bundled sample mission
#   make test   - the whole test suite
# Each creates the virtual environment it needs (.venv) on first use.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
SAMPLE ?= sample_data/missions/hidden-tam-contamination

.PHONY: run test bench clean-venv browser

$(STAMP): pyproject.toml
	@echo "make: first use: creating $(VENV) and installing GCS with its dependencies"
	@echo "      (numpy, scipy, h5py, numba, textual, pytest ...; about a minute, once)"
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	touch $(STAMP)
	@echo "make: $(VENV) is ready"

run: $(STAMP)
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

# NO_COLOR breaks the SVG snapshots, so it is removed from the environment here.
test: $(STAMP) browser
	env -u NO_COLOR OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 $(PYTEST_ARGS)

bench: $(STAMP)
	for f in benchmarks/*.py; do echo "== $$f"; $(BIN)/python $$f || exit 1; done

clean-venv:
	rm -rf $(VENV)
