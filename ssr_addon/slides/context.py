"""What every slide section uses: scenes, renders with their stage times, the Cycles reference,
errors against it and PNGs of images and data."""
import os
import time
from dataclasses import dataclass, replace

import numpy as np
import OpenImageIO as oiio

from ..bench.images import display
from ..bench.metrics import accuracy
from ..bench.references import DEFAULT_CACHE, render_reference
from ..bench.scenes import resolve_scene
from ..errors import SSRError
from ..operators import render_mode
from ..params import ChainSettings
from ..render_job import RenderRequest
from ..scene_io import load_scene


@dataclass
class Render:
    images: dict          # render_frame's images: final, passes, the chain's intermediates
    stages_ms: dict       # {stage: milliseconds}
    wall_ms: float        # the whole frame

    @property
    def final(self):
        return self.images["final"][..., :3]


class SlideContext:
    def __init__(self, out_dir, resolution, quick, log):
        self.out_dir, self.resolution, self.quick, self.log = out_dir, resolution, quick, log
        self.samples = 4 if quick else 16
        self.reference_samples = 64 if quick else 1024
        self._scenes, self._references, self._renders = {}, {}, {}

    def scene(self, name):
        """The test scene NAME (test_scenes/NAME.py), built once."""
        if name not in self._scenes:
            self._scenes[name] = load_scene(resolve_scene(name))
        return self._scenes[name]

    def render(self, name, mode="SSR", **settings):
        """A still of scene NAME in comparison MODE (settings.COMPARISON_MODES) with chain SETTINGS,
        rendered once per run (a still is the same image every time)."""
        key = (name, mode, tuple(sorted(settings.items())))
        if key not in self._renders:
            request = RenderRequest(out_dir=self.out_dir, resolution=self.resolution, samples=self.samples,
                                    settings=replace(ChainSettings(), **settings))
            started = time.perf_counter()
            images, timer = render_mode(self.scene(name), mode, request)
            self._renders[key] = Render(images, dict(timer.milliseconds), (time.perf_counter() - started) * 1000.0)
        return self._renders[key]

    def error(self, name, render):
        """FLIP and relative MAE on the reflective pixels against the Cycles reference of NAME."""
        if name not in self._references:
            scene = self.scene(name)
            self._references[name] = render_reference(scene, resolve_scene(name), self.resolution,
                                                      self.reference_samples, scene.frame_current, DEFAULT_CACHE,
                                                      self.log)
        reference = self._references[name]
        scores, _ = accuracy(reference.image, render.final, reference.mask)
        return {"flip": round(scores["flip_reflective"], 4), "rel_mae": round(scores["mae_reflective"], 4)}

    def save(self, file_name, rgb, data=False):
        """Write RGB (scene linear, through the bench's display transform; DATA: already in [0, 1])
        as OUT_DIR/FILE_NAME, a PNG; returns FILE_NAME."""
        shown = np.clip(rgb if data else display(rgb), 0.0, 1.0)
        pixels = np.ascontiguousarray((shown * 255.0 + 0.5).astype(np.uint8))
        path = os.path.join(self.out_dir, file_name)
        output = oiio.ImageOutput.create(path)
        if output is None or not output.open(path, oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, "uint8")) \
                or not output.write_image(pixels):
            raise SSRError(f"cannot write {path}: {oiio.geterror()}")
        output.close()
        return file_name
