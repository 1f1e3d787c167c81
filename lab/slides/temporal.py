"""The deck's temporal slides: the temporal filter off and on over a still camera's frames, and
reprojecting the hit point against the surface under camera motion. Motion is the point, so
each comes with an animated GIF."""
import numpy as np

from ..bench.metrics import flip_error
from ..bench.stability import LUMINANCE, relative_flicker
from .resolve import GLOSSY
from .section import CONVERGED, ONE_ITERATION, section

STILL_FRAMES = 8
MOVING = "stability_moving_camera"  # the camera slides sideways over a mirror floor with glowing blocks
REFLECTIONS_INSET = (0.2, 0.5, 0.7, 0.85)  # the blocks' reflections in the floor


def temporal_filter(context):
    mask = context.reference(GLOSSY).mask
    converged, = context.chain(GLOSSY, **CONVERGED)
    images, numbers = [], {}
    for use_temporal, name, label in ((False, "off", "Without temporal filter"), (True, "on", "With temporal filter")):
        frames = context.chain(GLOSSY, frames=STILL_FRAMES, use_temporal=use_temporal, **ONE_ITERATION)
        shown = np.stack([(render.final @ LUMINANCE)[mask] for render in frames])
        numbers[f"{name}_flicker"] = round(relative_flicker(shown, float(shown.mean())), 4)
        numbers[f"{name}_noise"] = context.noise(GLOSSY, frames[-1], converged)
        images.append((f"{label}, frames 1-{STILL_FRAMES}",
                       context.save_animation(f"temporal_{name}.gif", [render.final for render in frames]),
                       "animation"))
    return section("Temporal Reprojection (filtering)", images, numbers,
                   "1 ray per 2x2 pixels, 4 resolve samples, one iteration a frame, the camera still for "
                   f"{STILL_FRAMES} frames. Without the filter every frame shows its own noise: the "
                   "reflective pixels change by {off_flicker} of their brightness from one frame to the "
                   "next. With it, each frame blends into the last ones: {on_flicker}. By the last frame "
                   "the noise against the settled image is {off_noise} without and {on_noise} with it.")


def reprojection(context):
    scene = context.scene(MOVING)
    frame_numbers = list(range(scene.frame_start, scene.frame_end + 1))
    images, numbers = [], {}
    for mode, label in (("surface", "Reprojecting the reflecting surface"), ("hit", "Reprojecting the hit point")):
        frames = context.animation(MOVING, frame_numbers, temporal_reprojection=mode, noise_threshold=0.0)
        errors = []
        for frame, render in zip(frame_numbers[1:], frames[1:]):  # the first frame has no history
            reference = context.reference(MOVING, frame)
            errors.append(flip_error(reference.image, render.final, reference.mask))
        numbers[f"{mode}_flip"] = round(float(np.mean(errors)), 4)
        images.append((f"{label}, frames {frame_numbers[0]}-{frame_numbers[-1]}",
                       context.save_animation(f"reproject_{mode}.gif", [render.final for render in frames]),
                       "animation"))
        images.append((f"{label}, frame {frame_numbers[-1]}, the reflections enlarged",
                       context.save_inset(f"reproject_{mode}_inset.png", frames[-1].final, REFLECTIONS_INSET, zoom=2),
                       "inset"))
    return section("Temporal Reprojection: the hit point, not the surface", images, numbers,
                   "The camera slides sideways; after a settled first frame each frame traces one "
                   "iteration and leans on its history, as a real-time renderer does. A reflection "
                   "moves across the floor differently from the "
                   "floor itself, so history fetched where the floor was smears the reflection; fetched "
                   "where the reflected hit point was, it lines up. FLIP against Cycles over the frames "
                   "with history: {surface_flip} reprojecting the surface, {hit_flip} reprojecting the "
                   "hit point.")
