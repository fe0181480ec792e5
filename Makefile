# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO := demo-out
# Two workers on the 2-core machine: the suite is CPU-bound, one test per core.
PYTEST := $(BIN)/python -m pytest -q -n 2 -p no:cacheprovider

.PHONY: demo test test-slow test-all lint docs bench venv clean

# setuptools' notice that every editable install gets ("be careful with folders named as the
# package") is information, not a problem of this project: filtered by its exact words.
$(BIN)/seqdesign: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	PYTHONWARNINGS="ignore:Editable installation:UserWarning" $(BIN)/pip install --quiet -e '.[test,dask,plot,docs]'
	touch $@

venv: $(BIN)/seqdesign

demo: venv
	mkdir -p $(DEMO)
	$(BIN)/seqdesign show paper-9pos
	$(BIN)/seqdesign simulate paper-9pos --table2 --setup-deg 1 -2 3 --seed 7 -o $(DEMO)/run.npz
	$(BIN)/seqdesign analyze paper-9pos
	$(BIN)/seqdesign calibrate $(DEMO)/run.npz -o $(DEMO)/run.result.toml
	$(BIN)/seqdesign view $(DEMO)/run.npz -o $(DEMO)/run.rrd

# Lint (ruff rules and format), types (mypy), then the tests.
lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

# The fast suite: everything but the slow statistical and end-to-end tests.
test: lint
	$(PYTEST) -m "not slow"

# The slow statistical and end-to-end tests only; the slowest named, to keep CI well under 30 min.
test-slow: venv
	$(PYTEST) -m slow --durations=12

# Everything: the fast suite, then the slow tests (what CI runs).
test-all: test test-slow

# The API reference from the docstrings (Sphinx, sources in docs/api/) into docs/_build/html:
# every warning an error, every cross-reference resolved (nitpicky). The module pages are
# generated afresh from the packages each time, so a moved module leaves no stale page.
docs: venv
	rm -rf docs/_build docs/api/generated
	$(BIN)/python -m sphinx -b html -n -W --keep-going -q docs/api docs/_build/html
	@echo "API reference: docs/_build/html/index.html"

bench: venv
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) $(DEMO) docs/_build docs/api/generated
