# The README's two commands: `make run` (the station's main job on the simulated station) and `make test`.
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out

.PHONY: setup run demo test lint typecheck layers pytest bench clean

$(STAMP): pyproject.toml constraints.txt tools/setup.sh tools/apt-packages.txt
	VENV=$(VENV) bash tools/setup.sh
	touch $(STAMP)

setup: $(STAMP)

DATA ?= station-data

# The station's main job on the simulated station: a validation session (the seed's 40 positions, the
# simulated operator turning the micrometers) and a six-joint repeatability session, each recorded in
# $(DATA) with its report (tables, figures, HTML); the paths are printed at the end.
run: demo

demo: setup
	$(BIN)/station run validation --sim --data $(DATA) --report
	$(BIN)/station run repeatability --sim --param cycles=10 --data $(DATA) --report

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: setup
	$(BIN)/mypy

layers: setup
	$(BIN)/python tools/check_layers.py

pytest: setup
	$(BIN)/python -m pytest -n 2 -q

test: lint typecheck layers pytest

bench: setup
	$(BIN)/python -m bench
	$(BIN)/python -m bench.station_bench

clean:
	rm -rf $(VENV) $(OUT) .mypy_cache .ruff_cache .pytest_cache
