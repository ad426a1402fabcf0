# pendsweep: `make run` (Fig. 11(a) sweep and plot) and `make test` work on a
# fresh machine with Python 3.11 and make; both build .venv first.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: setup run test lint format figures architecture bench wheel-check clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	$(BIN)/pendsweep warmup  # compile every command's numba kernels once, so that the first run starts warm
	touch $(STAMP)

setup: $(STAMP)  ## create .venv, install pendsweep with its test tools, compile its kernels (pendsweep warmup)

run: $(STAMP)  ## the main job: Fig. 11(a) sweep -> results/fig11a.parquet and results/figures/fig11a.png
	$(BIN)/pendsweep run fig11a

test: lint  ## lint, then the test suite
	$(BIN)/python -m pytest -x -q

lint: $(STAMP)  ## ruff lint and format check, and the import layers (lint-imports; all in pyproject.toml)
	$(BIN)/ruff check src tests examples
	$(BIN)/ruff format --check src tests examples
	$(BIN)/lint-imports  # the layers contract in pyproject.toml (docs/architecture.md)

format: $(STAMP)  ## apply ruff's fixes and formatting
	$(BIN)/ruff check --fix src tests examples
	$(BIN)/ruff format src tests examples

figures: $(STAMP)  ## regenerate every figure into results/figures/
	$(BIN)/pendsweep figures -o results/figures

architecture: $(STAMP)  ## the layers and the imports between them, read from the code -> docs/img/layers.png
	$(BIN)/python scripts/layers_figure.py docs/img/layers.png

bench: $(STAMP)  ## benchmarks -> results/bench.json
	$(BIN)/python -m pendsweep.bench -o results/bench.json

wheel-check: $(STAMP)  ## build the wheel, install it in a fresh venv under /tmp, run it from an empty folder
	rm -rf /tmp/pendsweep-wheel-check && mkdir -p /tmp/pendsweep-wheel-check/run
	$(BIN)/python -m pip wheel --no-deps --quiet . -w /tmp/pendsweep-wheel-check/dist
	$(PYTHON) -m venv /tmp/pendsweep-wheel-check/venv
	/tmp/pendsweep-wheel-check/venv/bin/pip install --quiet /tmp/pendsweep-wheel-check/dist/*.whl
	cd /tmp/pendsweep-wheel-check/run && ../venv/bin/pendsweep run fig11a --no-progress \
	  && ../venv/bin/pendsweep figures fig8 && ../venv/bin/pendsweep hopf --what 1.1087 --method analytic \
	  && ../venv/bin/pendsweep hopf --what 1.0 --method analytic,floquet

clean:
	rm -rf $(VENV) results/*.parquet results/*.parts results/figures results/bench.json
