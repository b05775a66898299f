# The README's two commands: `make run` (the station's main job on the simulated station) and `make test`.
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out

.PHONY: setup run test lint typecheck layers pytest bench clean

$(STAMP): pyproject.toml constraints.txt tools/setup.sh tools/apt-packages.txt
	VENV=$(VENV) bash tools/setup.sh
	touch $(STAMP)

setup: $(STAMP)

# A simulated 40-position validation (the seed's section 4 pattern), measured, with the error table.
run: setup
	$(BIN)/station sim render-set $(OUT)/validation-nominal --pattern validation --preset nominal --seed 1 --force
	$(BIN)/station validate $(OUT)/validation-nominal

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

clean:
	rm -rf $(VENV) $(OUT) .mypy_cache .ruff_cache .pytest_cache
