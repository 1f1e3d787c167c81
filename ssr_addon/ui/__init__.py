"""The add-on's user interface: the scene settings, operators, panels, the viewport overlay and
live SSR, registered in order (Node Wrangler style) and unregistered in reverse."""
from . import live, operators, overlay, panels, properties

modules = (properties, operators, panels, overlay, live)


def register():
    for module in modules:
        module.register()


def unregister():
    for module in reversed(modules):
        module.unregister()
