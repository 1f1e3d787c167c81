"""Temporary changes to Blender data that are undone exactly, in reverse order."""


class TemporaryChanges:
    """Record every change made through it; `restore()` puts everything back.

    Use as a context manager so the user's scene is restored even when a render
    fails halfway.
    """

    def __init__(self):
        self._undo = []

    def set(self, owner, attribute, value):
        """Set OWNER.ATTRIBUTE to VALUE, to be put back; a property already at the value it gets is
        not written: Blender runs a property's update even then, and an update of the scene or the
        3D View starts EEVEE's viewport engine afresh."""
        old = getattr(owner, attribute)
        self._undo.append(lambda: _assign(owner, attribute, old))
        _assign(owner, attribute, value)

    def set_all(self, owner, **values):
        """Set several attributes of OWNER in the given order (media type before format...), and
        restore them in that same order: Blender coerces one by another, so restoring them in
        reverse would turn an 8-bit PNG's depth into 16 while the format is still EXR."""
        old = {attribute: getattr(owner, attribute) for attribute in values}

        def restore_in_order():
            for attribute, value in old.items():
                setattr(owner, attribute, value)
        self._undo.append(restore_in_order)
        for attribute, value in values.items():
            setattr(owner, attribute, value)

    def on_restore(self, undo):
        """Register a callable that undoes a change made directly (a new node, a new AOV...)."""
        self._undo.append(undo)

    def restore(self):
        while self._undo:
            self._undo.pop()()

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.restore()
        return False


def _assign(owner, attribute, value):
    try:
        same = bool(getattr(owner, attribute) == value)
    except (TypeError, ValueError):  # values that do not compare as one truth
        same = False
    if not same:
        setattr(owner, attribute, value)
