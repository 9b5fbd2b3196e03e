# Two commands do everything on a fresh machine: `make demo` and `make test`.
# Each bootstraps .venv from the package registry (PyPI) on first use.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
OUT    ?= demo_out

.PHONY: demo test lint bench clean venv qgis-plugin

venv: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	$(BIN)/toolbox -q warmup || echo "toolbox warmup failed: first runs will compile their kernels"
	touch $(STAMP)

demo: $(STAMP)  ## run the main job on bundled sample data into $(OUT)/
	$(BIN)/toolbox demo --out $(OUT)

test: $(STAMP)  ## run the test suite (one pytest-xdist worker per CPU)
	$(BIN)/python -m pytest -q -n auto --dist worksteal

lint: $(STAMP)  ## ruff, and the import contract of pyproject.toml [tool.importlinter]
	$(BIN)/ruff check toolbox algorithms tests bench qgis_plugin
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)  ## benchmarks against peers (see bench/RESULTS.md)
	$(BIN)/python bench/run_all.py

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache build *.egg-info

qgis-plugin:  ## the QGIS plugin as a zip for "Install from ZIP" (dist/photogrammetry_toolbox.zip)
	mkdir -p dist
	$(PYTHON) -c "import pathlib, zipfile; z = zipfile.ZipFile('dist/photogrammetry_toolbox.zip', 'w', zipfile.ZIP_DEFLATED); [z.write(f, f.relative_to('qgis_plugin')) for f in sorted(pathlib.Path('qgis_plugin/photogrammetry_toolbox').rglob('*')) if '__pycache__' not in f.parts]; z.close()"
	@echo "dist/photogrammetry_toolbox.zip: QGIS > Plugins > Manage and Install Plugins > Install from ZIP"
