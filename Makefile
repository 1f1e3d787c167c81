# Everything runs inside .venv, created on first use from pyproject.toml.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= out/demo
BLENDER_EXT := $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py

.PHONY: demo test bench bench-chain bench-memory dist validate clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

# Renders the bundled demo scene with SSR off and on, side by side in $(OUT).
demo: $(STAMP)
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method none --out $(OUT)/none
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method ssr --out $(OUT)/ssr

test: $(STAMP)
	$(PY) -m pytest tests

# Regenerates docs/bench/ and the README's chart and table.
bench: $(STAMP)
	$(PY) -m ssr_addon bench --scenes mirror_floor rough_spheres curved_mirror rolling_ball wet_street --resolution 160x90 --out docs/bench --readme README.md

bench-chain: $(STAMP)
	$(PY) benchmarks/chain_stages.py

bench-memory: $(STAMP)
	$(PY) benchmarks/batch_memory.py

validate: $(STAMP)
	$(PY) $(BLENDER_EXT) validate .

dist: $(STAMP)
	mkdir -p dist
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir dist

clean:
	rm -rf out dist .pytest_cache
