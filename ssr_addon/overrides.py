"""Temporary changes to Blender data that are undone exactly, in reverse order."""


class TemporaryChanges:
    """Record every change made through it; `restore()` puts everything back.

    Use as a context manager so the user's scene is restored even when a render
    fails halfway.
    """

    def __init__(self):
        self._undo = []

    def set(self, owner, attribute, value):
        old = getattr(owner, attribute)
        self._undo.append(lambda: setattr(owner, attribute, old))
        setattr(owner, attribute, value)

    def set_all(self, owner, **values):
        """Set several attributes of OWNER, in the given order (media type before format...)."""
        for attribute, value in values.items():
            self.set(owner, attribute, value)

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
