"""The one exception type the add-on raises for bad input or environment.

The CLI prints its message as a single line and exits non-zero; operators
report it in Blender's status bar. Anything else is a bug.
"""


class SSRError(Exception):
    """A problem the user can fix: missing camera, missing pass, bad argument..."""
