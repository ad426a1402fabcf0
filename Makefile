# pendsweep: `make run` (Fig. 11(a) sweep and plot) and `make test` work on a
# fresh machine with Python 3.11 and make; both build .venv first.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: setup run test figures bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

setup: $(STAMP)  ## create .venv and install pendsweep with its test tools

run: $(STAMP)  ## the main job: Fig. 11(a) sweep -> results/fig11a.parquet and results/figures/fig11a.png
	$(BIN)/pendsweep run sweeps/fig11a.toml

test: $(STAMP)  ## the test suite
	$(BIN)/python -m pytest -x -q

figures: $(STAMP)  ## regenerate every figure into results/figures/
	$(BIN)/pendsweep figures --out results/figures

bench: $(STAMP)  ## benchmarks -> results/bench.json
	$(BIN)/python -m pendsweep.bench -o results/bench.json

clean:
	rm -rf $(VENV) results/*.parquet results/*.parts results/figures results/bench.json
