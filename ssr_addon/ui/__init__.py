"""The add-on's user interface: panels, the viewport overlay and live SSR."""
from . import live, overlay, panels

modules = (panels, overlay, live)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
