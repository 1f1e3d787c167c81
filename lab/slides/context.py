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
from ssr_addon.batch.compare import render_mode
from ssr_addon.batch.frame import FrameFallbacks, FrameImages, chain_stats
from ssr_addon.batch.request import RenderRequest
from ssr_addon.blender.lamp_renders import lamp_world_for_run
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.chain import ChainState, run_chain
from ssr_addon.core.errors import SSRError
from ssr_addon.core.gpu_backend import StageTimer, download
from ssr_addon.core.inputs import ChainInputs
from ssr_addon.core.layers import read_layers
from ssr_addon.core.settings import ChainSettings

GIF_FRAME_MS = 250  # an animation's frames, slowed so each can be looked at


@dataclass
class Render:
    images: FrameImages   # render_frame's: final, passes, every layer
    stages_ms: dict       # {stage: milliseconds}
    wall_ms: float        # the whole frame

    @property
    def final(self):
        return self.images.final[..., :3]

    def iteration_ms(self, stage):
        """STAGE's milliseconds per trace iteration of the frame, rounded for a caption."""
        return round(self.stages_ms.get(stage, 0.0) / self.images.stats["iterations"], 1)


class SlideContext:
    def __init__(self, out_dir, resolution, quick, log):
        self.out_dir, self.resolution, self.quick, self.log = out_dir, resolution, quick, log
        self.samples = 4 if quick else 16
        # 256: a new scene's reference takes minutes, not a quarter of an hour, on two CPU cores; the
        # bench's references (2048 samples) are the ones its precise numbers come from.
        self.reference_samples = 64 if quick else 256
        self._scene = None  # (name, the loaded scene)
        self._references, self._renders, self._chains = {}, {}, {}
        self._warmed = set()  # (scene name, mode) rendered once since the scene was loaded

    def scene(self, name):
        """The test scene NAME (test_scenes/NAME.py). Loading a scene replaces Blender's file, so
        only the last one loaded is alive: another name builds its scene afresh."""
        if self._scene is None or self._scene[0] != name:
            self._scene = (name, load_scene(resolve_scene(name)))
            self._warmed = set()  # a loaded file brings new materials: their shaders compile again
        return self._scene[1]

    def render(self, name, mode="SSR", **settings):
        """A still of scene NAME in comparison MODE (baselines.COMPARISON_MODES) with chain SETTINGS,
        rendered once per run (a still is the same image every time)."""
        key = (name, mode, tuple(sorted(settings.items())))
        if key not in self._renders:
            self._renders[key] = self.render_afresh(name, mode, **settings)
        return self._renders[key]

    def render_afresh(self, name, mode="SSR", **settings):
        """render() without its cache: for a scene changed for one measurement (objects added...).
        The first render of a scene in a mode compiles its shaders (seconds); it runs once untimed
        so that a frame's milliseconds are a frame's."""
        if (name, mode) not in self._warmed:
            self._timed_render(self.scene(name), mode, settings)
            self._warmed.add((name, mode))
        return self._timed_render(self.scene(name), mode, settings)

    def _timed_render(self, scene, mode, settings, state=None, fallbacks=None):
        """render_mode of SCENE's current frame at the run's size and samples, as a Render."""
        request = RenderRequest(out_dir=self.out_dir, resolution=self.resolution, samples=self.samples,
                                settings=replace(ChainSettings(), **settings), time_stages=True)
        started = time.perf_counter()
        images, timer = render_mode(scene, mode, request, state, fallbacks)
        return Render(images, dict(timer.milliseconds), (time.perf_counter() - started) * 1000.0)

    def chain(self, name, frames=1, **settings):
        """The chain alone, with SETTINGS, on the passes of NAME's SSR still (render()), run as FRAMES
        frames of a camera that holds still (a still when 1); returns a Render per frame, its
        milliseconds the chain's own. Variants of the chain share one engine render this way, and
        each runs once per run."""
        key = (name, frames, tuple(sorted(settings.items())))
        if key not in self._chains:
            self._chains[key] = self._run_chain(name, frames, settings)
        return self._chains[key]

    def _run_chain(self, name, frames, settings):
        passes = self.render(name).images.passes
        chain_settings = replace(ChainSettings(), **settings)
        inputs = ChainInputs.from_passes(passes, chain_settings)
        state = ChainState.still() if frames == 1 else ChainState()
        renders = []
        for frame in range(1, frames + 1):
            state.begin_frame(frame)
            timer = StageTimer()
            outputs = run_chain(inputs, chain_settings, state, timer)
            layers = read_layers(passes, outputs)
            images = FrameImages(passes, download(outputs["final"]), layers,
                                 chain_stats(outputs, passes, layers, chain_settings))
            renders.append(Render(images, dict(timer.milliseconds), sum(timer.milliseconds.values())))
        return renders

    def animation(self, name, frames, **settings):
        """Frames FRAMES of scene NAME's own animation in SSR mode, history carried from frame to
        frame as a batch render carries it; a Render per frame."""
        scene = self.scene(name)
        state, fallbacks, renders = ChainState(), FrameFallbacks(), []
        try:
            with lamp_world_for_run():
                for frame in frames:
                    scene.frame_set(frame)
                    state.begin_frame(frame, scene.camera.name)
                    renders.append(self._timed_render(scene, "SSR", settings, state, fallbacks))
        finally:
            fallbacks.release()
        return renders

    def error(self, name, render):
        """FLIP and relative MAE on the reflective pixels against the Cycles reference of NAME."""
        reference = self.reference(name)
        scores, _ = accuracy(reference.image, render.final, reference.mask)
        return {"flip": round(scores["flip_reflective"], 4), "rel_mae": round(scores["mae_reflective"], 4)}

    def reference(self, name, frame=None):
        """The Cycles reference of NAME at FRAME (default: the scene's current frame), cached on disk."""
        if (name, frame) not in self._references:
            scene = self.scene(name)
            self._references[name, frame] = render_reference(
                scene, resolve_scene(name), self.resolution, self.reference_samples,
                scene.frame_current if frame is None else frame, DEFAULT_CACHE, self.log)
        return self._references[name, frame]

    def noise(self, name, render, converged):
        """Mean absolute difference of RENDER from CONVERGED (the chain run until settled) on the
        reflective pixels, relative to their mean: the noise alone, without the error both share."""
        mask = self.reference(name).mask
        shown, settled = (r.final[mask] for r in (render, converged))
        return round(float(np.mean(np.abs(shown - settled)) / max(np.mean(settled), 1e-6)), 4)

    def save(self, file_name, rgb, data=False):
        """Write RGB (scene linear, through the bench's display transform; DATA: already in [0, 1])
        as OUT_DIR/FILE_NAME, a PNG; returns FILE_NAME."""
        pixels = _display_bytes(rgb, data)
        path = os.path.join(self.out_dir, file_name)
        output = oiio.ImageOutput.create(path)
        if output is None or not output.open(path, oiio.ImageSpec(pixels.shape[1], pixels.shape[0], 3, "uint8")) \
                or not output.write_image(pixels):
            raise SSRError(f"cannot write {path}: {oiio.geterror()}")
        output.close()
        return file_name

    def save_inset(self, file_name, rgb, box, zoom=4):
        """Write the part BOX (left, top, right, bottom as fractions of the image) of RGB, each
        pixel ZOOM pixels wide, as a PNG: a difference too small to see at full view; returns FILE_NAME."""
        height, width = rgb.shape[:2]
        left, top, right, bottom = (int(round(f * n)) for f, n in zip(box, (width, height, width, height)))
        crop = rgb[top:max(bottom, top + 1), left:max(right, left + 1)]
        return self.save(file_name, crop.repeat(zoom, axis=0).repeat(zoom, axis=1))

    def save_animation(self, file_name, frames):
        """Write FRAMES (scene-linear RGB arrays) as a looping GIF; returns FILE_NAME."""
        from PIL import Image  # matplotlib's image library, a dependency of the bench
        images = [Image.fromarray(_display_bytes(rgb)) for rgb in frames]
        path = os.path.join(self.out_dir, file_name)
        images[0].save(path, save_all=True, append_images=images[1:], duration=GIF_FRAME_MS, loop=0)
        return file_name


def _display_bytes(rgb, data=False):
    """RGB as 8-bit display values: scene linear through the bench's display transform (DATA: already in [0, 1])."""
    shown = np.clip(rgb if data else display(rgb), 0.0, 1.0)
    return np.ascontiguousarray((shown * 255.0 + 0.5).astype(np.uint8))
