# The README's two commands: `make run` (the station as a service on the simulated station) and `make test`.
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out

.PHONY: setup run demo test lint typecheck layers pytest bench clean

$(STAMP): pyproject.toml setup.py station/vision/_ckernels.c $(wildcard station/vision/_ruler_*.[ch]) constraints.txt tools/setup.sh tools/apt-packages.txt
	VENV=$(VENV) bash tools/setup.sh
	touch $(STAMP)

setup: $(STAMP)

DATA ?= station-data

# The station's main job: the service on the simulated station. `station serve` prints the operator page's
# URL (carrying a new token unless STATION_API_TOKEN is set) and runs until Ctrl-C, which stops the arm,
# records a running session as interrupted and closes the devices. MANUAL=1: a person answers the table's
# micrometer prompts in the page (the simulated operator is off).
PORT ?= 8465
run: setup
	$(BIN)/station serve --sim --data $(DATA) --port $(PORT) $(if $(MANUAL),--manual-prompts,)

# The finite demonstration: a validation session (the seed's 40 positions, the simulated operator turning
# the micrometers) and a six-joint repeatability session, each recorded in $(DATA) with its report.
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

# The GigE simulator's tests and the Dask cluster's (a scheduler and workers started on localhost) run
# apart from the rest: both suffer when the machine is loaded by the parallel run. `--dist loadfile` keeps
# a test file on one worker, so that its module fixtures (a simulated calibration session, shared
# services, rendered image sets) are built once, not once per worker that happens to run one of its tests.
# `--durations` lists the slowest tests (set-up included) at the end of the run: where the suite's time goes.
pytest: setup
	$(BIN)/python -m pytest -n 2 --dist loadfile -q -m "not gige and not cluster" --durations=30
	$(BIN)/python -m pytest -q -m gige
	$(BIN)/python -m pytest -q -m cluster

test: lint typecheck layers pytest

bench: setup
	$(BIN)/python -m bench
	$(BIN)/python -m bench.ruler_bench
	$(BIN)/python -m bench.station_bench
	$(BIN)/python -m bench.compute_bench
	$(BIN)/python -m bench.archive_bench
	$(BIN)/python -m bench.service_load
	$(BIN)/python -m bench.service_memory
	$(BIN)/python -m bench.api_fuzz
	$(BIN)/python -m bench.calibration_bench --seeds 10
	$(BIN)/python -m bench.calibration_session_bench
	$(BIN)/python -m bench.cross_check_bench
	$(BIN)/python -m bench.camcal_bench
	$(BIN)/python -m bench.target_render_bench
	$(BIN)/python -m bench.page_screens --out $(OUT)/page

clean:
	rm -rf $(VENV) $(OUT) .mypy_cache .ruff_cache .pytest_cache
