"""Speed against accuracy: `python -m lab bench [--scenes ...] [--resolution WxH] --out DIR`.

Every contender renders the same scenes: no SSR (probe/world reflections),
EEVEE's own screen-space ray tracing at its default and at its highest
quality, and this project at each preset and with each stage switched off in
turn. Each is scored against a Cycles path trace (rendered once, cached by a
hash of scene, resolution and settings) and timed per frame and, for ours,
per stage, also as a multiple of a full-screen copy pass timed in the same
run. The stability cases (test_scenes/stability_*.py) run over short
animations and are measured with the functions tests/test_stability.py
asserts on, so the bench's numbers and the tests' verdicts cannot drift apart.

A development tool: flip-evaluator, scikit-image and matplotlib are dev
dependencies, imported only inside the functions that use them.
"""
from .contenders import all_contenders
from .images import display, layer_rgb, read_channels
from .metrics import flip_error, reflective_mask, relative_mae
from .page_block import update_page
from .references import DEFAULT_CACHE, REFERENCE_SAMPLES, render_reference
from .run import DEFAULT_FRAMES, DEFAULT_RESOLUTION, DEFAULT_SCENES, EEVEE_SAMPLES, options_from_arguments, run_bench
from .speed import copy_pass_ms, queued_copy_pass_ms
from .stability import (ENERGY_TOLERANCE, FALLBACK_MARGIN, FLICKER_LIMIT, SEAM_LIMIT, STABILITY_FRAMES, energy_excess,
                        evaluate_case, flicker, seam_strength, stability_cases)
