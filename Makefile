# Two commands do everything on a fresh machine: `make demo` and `make test`.
# Each bootstraps .venv from the package registry (PyPI) on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= demo_out

.PHONY: demo test lint bench clean venv

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

demo: $(STAMP)  ## run the main job on bundled sample data into $(OUT)/
	$(BIN)/toolbox demo --out $(OUT)

test: $(STAMP)  ## run the test suite
	$(BIN)/python -m pytest -q

lint: $(STAMP)  ## ruff, and the import contract of pyproject.toml [tool.importlinter]
	$(BIN)/ruff check toolbox algorithms tests bench
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)  ## benchmarks against peers (see bench/RESULTS.md)
	$(BIN)/python bench/run_all.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache build *.egg-info
