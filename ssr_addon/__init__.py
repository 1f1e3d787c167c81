"""Stochastic SSR: Frostbite-style screen-space reflections for EEVEE and Cycles renders.

As a Blender add-on it registers the user interface (ui: the scene settings, operators,
panels, overlay and live mode). Importing touches no GPU, so it works headless.

Layers, each importing only those below it (tests/test_layers.py holds them):
core (the GPU chain, `gpu` only), blender (render passes, captures, user data),
batch (command line, frame loop, outputs) and ui.
"""
from .ui import register, unregister  # noqa: F401
