"""Stochastic SSR: Frostbite-style screen-space reflections for EEVEE and Cycles renders.

As a Blender add-on: registers the scene settings, the operators and the UI
(Node Wrangler style, in order; unregistered in reverse). Nothing here touches
the GPU, so importing works headless and without a GPU context.
"""
from . import operators, settings, ui

modules = (settings, operators, ui)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
