# Two commands on a fresh machine: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO := demo-out

.PHONY: demo test bench venv clean

$(BIN)/seqdesign: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test,dask,plot]'
	touch $@

venv: $(BIN)/seqdesign

demo: venv
	mkdir -p $(DEMO)
	$(BIN)/seqdesign show paper-9pos
	$(BIN)/seqdesign simulate paper-9pos --table2 --setup-deg 1 -2 3 --seed 7 -o $(DEMO)/run.npz
	$(BIN)/seqdesign analyze paper-9pos
	$(BIN)/seqdesign calibrate $(DEMO)/run.npz -o $(DEMO)/run.result.toml
	$(BIN)/seqdesign view $(DEMO)/run.npz -o $(DEMO)/run.rrd

test: venv
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

bench: venv
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) $(DEMO)
