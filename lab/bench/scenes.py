"""The bench's scenes: names in test_scenes/ or scene files, and their labels."""
import os

from ssr_addon.core.errors import SSRError

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENES_DIR = os.path.join(REPO, "test_scenes")


def resolve_scene(name):
    """A scene name from test_scenes/ or a path to a .blend or .py scene."""
    path = name if os.path.splitext(name)[1] else os.path.join(SCENES_DIR, f"{name}.py")
    if not os.path.isfile(path):
        raise SSRError(f"scene {name!r} not found (neither a file nor a scene in {SCENES_DIR})")
    return os.path.abspath(path)


def scene_label(path):
    return os.path.splitext(os.path.basename(path))[0]
