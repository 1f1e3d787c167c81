"""The add-on's user interface: panels and the viewport overlay."""
from . import overlay, panels

modules = (panels, overlay)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
