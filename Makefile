# Everything runs inside .venv, created on first use from pyproject.toml.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= out/demo
# The page whose generated blocks the measuring targets rewrite.
PAGE := docs/measurements.md
BLENDER_EXT := $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py

.PHONY: demo test test-fast bench bench-stages bench-error crops bench-chain bench-memory bench-lamps bench-live \
	bench-captures slides \
	dist validate clean

# Node runs the Flamenco job type's test; package.json pins it as a dev dependency.
NODE_STAMP := node_modules/.installed

$(NODE_STAMP): package.json package-lock.json
	npm ci --no-audit --no-fund --loglevel=error
	touch $(NODE_STAMP)

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

# Two test processes, each test file whole in one (its module fixtures render once): on two cores
# the suite takes about half as long as in one process.
TEST_WORKERS := -n 2 --dist loadfile

# Renders the bundled demo scene with SSR off and on into $(OUT)/none and $(OUT)/ssr, then
# writes them side by side ($(OUT)/side_by_side.png) and prints its path.
demo: $(STAMP)
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method none --out $(OUT)/none --overwrite
	$(PY) -m ssr_addon render test_scenes/mirror_floor.py --method ssr --out $(OUT)/ssr --overwrite
	$(PY) -m lab demo test_scenes/mirror_floor.py $(OUT)

test: $(STAMP) $(NODE_STAMP)
	$(PY) -m pytest tests $(TEST_WORKERS)

# The developer's loop: everything but the tests marked slow (EEVEE and Cycles renders, the CLI end to end).
test-fast: $(STAMP) $(NODE_STAMP)
	$(PY) -m pytest tests -m "not slow" $(TEST_WORKERS)

BENCH_SCENES := mirror_floor glossy_corridor rough_spheres curved_mirror rolling_ball wet_street

# Regenerates docs/bench/ and the measurements page's chart and tables: every scene, the
# engine alone, EEVEE's ray tracing and our presets, 8 frames each: errors on
# frame 8, as the "Right before new" issue asks, and each stage's fastest of
# 7 timed frames (about two hours on llvmpipe).
bench: $(STAMP)
	$(PY) -m lab bench --scenes $(BENCH_SCENES) --resolution 160x90 --frames 8 --out docs/bench --page $(PAGE) \
		--contenders none 'eevee-rt*' 'ssr draft' 'ssr balanced' 'ssr balanced lamp_split=unshadowed' \
		'ssr balanced lamp_split=render' 'ssr high'

# What each stage buys: the balanced preset with each stage switched off in turn.
bench-stages: $(STAMP)
	$(PY) -m lab bench --scenes mirror_floor wet_street --resolution 160x90 --out docs/bench-stages \
		--contenders 'ssr balanced fallback=off' 'ssr *=off' --no-stability

# Where the balanced preset's error comes from: the chain, EEVEE's frame or screen space itself.
bench-error: $(STAMP)
	$(PY) -m lab error-budget --scenes $(BENCH_SCENES) --frame 8 --page $(PAGE)

# Balanced stills at 1280x720 beside EEVEE's ray tracing, cropped (docs/crops/).
crops: $(STAMP)
	$(PY) -m lab crops --scenes mirror_floor wet_street --page $(PAGE)

# What the fallback hierarchy's captures cost, drawn through the 3D View or rendered.
bench-captures: $(STAMP)
	$(PY) -m lab captures --page $(PAGE)

bench-chain: $(STAMP)
	$(PY) -m lab chain-stages --page $(PAGE)

bench-memory: $(STAMP)
	$(PY) -m lab memory --page $(PAGE)

bench-lamps: $(STAMP)
	$(PY) -m lab lamps --page $(PAGE)

# Latency of live SSR from a view change to the first image and to convergence (docs/live/).
bench-live: $(STAMP)
	$(PY) -m lab live --page $(PAGE)

# The deck's comparisons, rendered and measured (docs/slides/index.html, its PNGs, slides.json).
slides: $(STAMP)
	$(PY) -m lab slides --out docs/slides

validate: $(STAMP)
	$(PY) $(BLENDER_EXT) validate .

dist: $(STAMP)
	mkdir -p dist
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir dist

clean:
	rm -rf out dist .pytest_cache
