"""Writing frames: every file goes to a temporary name first and is renamed when complete,
so an interrupted run leaves only whole files behind."""
import json
import math
import os
import signal
import threading
from contextlib import contextmanager

import numpy as np
import OpenImageIO as oiio

from ..core.errors import SSRError


def _partial_name(path):
    folder, name = os.path.split(path)
    return os.path.join(folder, f".{name}.partial")


def _discard(partial):
    if os.path.exists(partial):
        os.remove(partial)


@contextmanager
def written_together(paths):
    """Yield temporary names for PATHS; when the block succeeds rename them, in order, to
    PATHS; when it fails remove them. A reader never sees a half-written file."""
    partials = [_partial_name(path) for path in paths]
    try:
        yield partials
        for partial, path in zip(partials, paths):
            os.replace(partial, path)
    finally:
        for partial in partials:
            _discard(partial)


@contextmanager
def signals_held():
    """Hold SIGTERM and Ctrl-C until the block ends, then act on the first that came: what the
    block writes together (a frame and its report entry) is never split by them."""
    if threading.current_thread() is not threading.main_thread():  # only the main thread has handlers
        yield
        return
    caught = []
    # A handler set outside Python (getsignal is None) cannot be put back, so it is left alone.
    held = [signum for signum in (signal.SIGTERM, signal.SIGINT) if signal.getsignal(signum) is not None]
    previous = {signum: signal.signal(signum, lambda signum, frame: caught.append(signum)) for signum in held}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if caught:
            signal.raise_signal(caught[0])


def write_exr(path, channels):
    """Write {channel name: (H, W) float32} as one single-part float EXR, channels in the given order.

    Writes PATH directly: callers go through `written_together`.

    Names of the form "Layer.C" make it a layered EXR that Blender and
    compositing packages read as passes.
    """
    names = list(channels)
    pixels = np.stack([np.asarray(channels[name], dtype=np.float32) for name in names], axis=-1)
    height, width = pixels.shape[:2]
    spec = oiio.ImageSpec(width, height, len(names), "float")
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    output = oiio.ImageOutput.create("openexr")
    if output is None or not output.open(path, spec):
        raise SSRError(f"cannot write {path}: {oiio.geterror() or (output and output.geterror())}")
    written = output.write_image(np.ascontiguousarray(pixels))
    output.close()
    if not written:
        raise SSRError(f"cannot write {path}: {output.geterror()}")


def write_rgba_exr(path, rgba):
    write_exr(path, {name: rgba[..., index] for index, name in enumerate("RGBA")})


def read_rgba_exr(path):
    """The (H, W, 4) float32 image write_rgba_exr wrote to PATH."""
    image = oiio.ImageBuf(path)
    if image.has_error:
        raise SSRError(f"cannot read {path}: {image.geterror()}")
    return np.asarray(image.get_pixels(oiio.FLOAT), np.float32)


def write_json(path, data):
    """Strict JSON (readable by any parser): a NaN or infinite number is written as null."""
    with written_together([path]) as (partial,), open(partial, "w", encoding="utf-8") as stream:
        json.dump(_finite(data), stream, indent=2, allow_nan=False)
        stream.write("\n")


def _finite(value):
    if isinstance(value, dict):
        return {key: _finite(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite(item) for item in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def remove_partials(paths):
    """Remove what an interrupted write of PATHS left (written_together's temporary names)."""
    for path in paths:
        _discard(_partial_name(path))


def prepare_output_folder(folder, remove_leftovers=True):
    """Create FOLDER, or check it is writable; REMOVE_LEFTOVERS: every temporary file an interrupted
    write left there (not where other runs may be writing into it at the same time)."""
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as error:
        raise SSRError(f"cannot create output folder {folder}: {error.strerror}") from None
    if not os.access(folder, os.W_OK):
        raise SSRError(f"output folder {folder} is not writable")
    if not remove_leftovers:
        return
    for name in os.listdir(folder):
        if name.startswith(".") and name.endswith(".partial"):
            os.remove(os.path.join(folder, name))
