# Everything runs inside .venv, created on first use from pyproject.toml.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= out/demo
BLENDER_EXT := $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py

.PHONY: demo test bench bench-stages bench-error crops bench-chain bench-memory bench-lamps bench-live slides dist validate clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

# Renders the bundled demo scene with SSR off and on, side by side in $(OUT).
demo: $(STAMP)
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method none --out $(OUT)/none --overwrite
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method ssr --out $(OUT)/ssr --overwrite

test: $(STAMP)
	$(PY) -m pytest tests

BENCH_SCENES := mirror_floor glossy_corridor rough_spheres curved_mirror rolling_ball wet_street

# Regenerates docs/bench/ and the README's chart and tables: every scene, the
# engine alone, EEVEE's ray tracing and our presets, 8 frames each: errors on
# frame 8, as the "Right before new" issue asks, and each stage's fastest of
# 7 timed frames (about two hours on llvmpipe).
bench: $(STAMP)
	$(PY) -m ssr_addon bench --scenes $(BENCH_SCENES) --resolution 160x90 --frames 8 --out docs/bench --readme README.md \
		--contenders none 'eevee-rt*' 'ssr draft' 'ssr balanced' 'ssr balanced lamp_split=unshadowed' \
		'ssr balanced lamp_split=render' 'ssr high'

# What each stage buys: the balanced preset with each stage switched off in turn.
bench-stages: $(STAMP)
	$(PY) -m ssr_addon bench --scenes mirror_floor wet_street --resolution 160x90 --out docs/bench-stages \
		--contenders 'ssr balanced' 'ssr *=off' --no-stability

# Where the balanced preset's error comes from: the chain, EEVEE's frame or screen space itself.
bench-error: $(STAMP)
	$(PY) benchmarks/error_budget.py --scenes $(BENCH_SCENES) --frame 8 --readme README.md

# Balanced stills at 1280x720 beside EEVEE's ray tracing, cropped (docs/crops/).
crops: $(STAMP)
	$(PY) benchmarks/still_crops.py --scenes mirror_floor wet_street --readme README.md

bench-chain: $(STAMP)
	$(PY) benchmarks/chain_stages.py --readme README.md

bench-memory: $(STAMP)
	$(PY) benchmarks/batch_memory.py

bench-lamps: $(STAMP)
	$(PY) benchmarks/lamp_split.py --readme README.md

# Latency of live SSR from a view change to the first image and to convergence (docs/live/).
bench-live: $(STAMP)
	$(PY) benchmarks/live_latency.py --readme README.md

# The deck's comparisons, rendered and measured (docs/slides/index.html, its PNGs, slides.json).
slides: $(STAMP)
	$(PY) -m ssr_addon slides --out docs/slides

validate: $(STAMP)
	$(PY) $(BLENDER_EXT) validate .

dist: $(STAMP)
	mkdir -p dist
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir dist

clean:
	rm -rf out dist .pytest_cache
