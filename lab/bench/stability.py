"""Stability cases (test_scenes/stability_*.py): energy, seam, flicker and ghosting measurements, asserted by
tests/test_stability.py, and running every case for the bench."""
import ast
import json
import os
from dataclasses import replace

import numpy as np

from ssr_addon.batch.request import RenderRequest
from ssr_addon.batch.run import run_render
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.settings import ChainSettings
from .images import layer_rgb, render_folder_frame
from .metrics import _format, _mean, flip_error
from .references import render_reference
from .scenes import SCENES_DIR

# Stability cases: the animation every case renders, and the limits
# tests/test_stability.py asserts (drawn in stability.png).
STABILITY_FRAMES = (1, 4)
# Mean FLIP on reflective pixels that SSR may lose against the probe/world fallback:
# a case SSR cannot solve must fall back, not invent a worse reflection.
FALLBACK_MARGIN = 0.02
# Relative float tolerance of the energy bound (the composite runs in 32-bit floats).
ENERGY_TOLERANCE = 1e-3
# Largest share of the SSR-vs-fallback difference the image may cross in one pixel
# beyond what the reference does there (95th percentile over the fade's pixel pairs).
SEAM_LIMIT = 0.5
# Largest mean frame-to-frame change of the reflection layer, relative to the reflective pixels'
# brightness, with nothing moving (the temporal filter off measures about 0.06 on the thin case).
FLICKER_LIMIT = 0.05
LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)


def stability_cases():
    """{case name: motion} of test_scenes/stability_*.py; motion is None, "camera" or "object"."""
    cases = {}
    for name in sorted(os.listdir(SCENES_DIR)):
        if name.startswith("stability_") and name.endswith(".py"):
            with open(os.path.join(SCENES_DIR, name), encoding="utf-8") as source:
                tree = ast.parse(source.read())
            motion = next(ast.literal_eval(node.value) for node in tree.body if isinstance(node, ast.Assign)
                          and any(getattr(target, "id", None) == "MOTION" for target in node.targets))
            cases[name[:-3]] = motion
    return cases


def energy_excess(final, passes, brightest):
    """How far the frame exceeds the energy bound, as a fraction of the brightest radiance B.

    The composite computes final = combined + FG * (c R) - c * min(s * I, combined), with
    c R the premultiplied "SSR Reflection" layer (c the confidence), s the specular
    colour and I the indirect specular (probe/world) light; so the light SSR
    put in is added = final - combined + c min(s I, combined) = FG * c R (before the
    composite's clamp at 0). SSR only fetches, filters and accumulates radiance
    that this or an earlier frame showed, so R <= B (per channel, B the
    brightest Combined pixel so far), and a surface reflects at most what
    reaches it (FG <= 1). So per pixel and channel:
        c R <= c B   and   0 <= added <= c R.
    At most ENERGY_TOLERANCE means it holds (the composite runs in 32-bit floats).
    """
    confidence = passes["SSR Confidence.V"][..., None]
    combined = layer_rgb(passes, "Combined")
    # The composite takes out no more probe reflection than the pixel's image holds.
    probe = np.minimum(layer_rgb(passes, "Specular Color") * layer_rgb(passes, "Specular Indirect"),
                       np.maximum(combined, 0.0))
    added = final - combined + confidence * probe
    premultiplied = layer_rgb(passes, "SSR Reflection")
    excesses = (premultiplied - confidence * brightest, added - premultiplied, -added)
    return float(max((excess / np.maximum(brightest, 1e-6)).max() for excess in excesses))


def _local_step(luma):
    """Per pixel, the largest step to a 4-neighbour anywhere within one pixel of it."""
    height, width = luma.shape
    padded = np.pad(luma, 1, mode="edge")
    step = np.max([np.abs(padded[1 + dy:1 + dy + height, 1 + dx:1 + dx + width] - luma)
                   for dy, dx in ((-1, 0), (1, 0), (0, -1), (0, 1))], axis=0)
    padded = np.pad(step, 1, mode="edge")
    return np.max([padded[dy:dy + height, dx:dx + width] for dy in range(3) for dx in range(3)], axis=0)


def seam_strength(final, passes, reference, mask):
    """How hard SSR's hand-over to the fallback is: about 0 a smooth fade, about 1 a one-pixel cut.

    Over neighbouring pixel pairs on one reflective surface where the confidence
    changes, the final image's step beyond the largest step the reference makes
    within a pixel of the pair (so reflected silhouettes, which the reference
    has too, do not count even a pixel off), divided by the SSR-vs-fallback
    difference being faded there (the step a one-pixel cut would make). The
    composite blends final = combined + c D, so D = (final - combined) / c,
    known where the confidence c is above 0.
    Returns the 95th percentile, or None when the frame has no such pairs.
    """
    confidence = passes["SSR Confidence.V"]
    change = np.abs(final - layer_rgb(passes, "Combined")) @ LUMINANCE
    difference = np.where(confidence > 0.01, change / np.maximum(confidence, 0.01), 0.0)
    per_pixel = {"mask": mask, "depth": passes["Depth.Z"], "normal": layer_rgb(passes, "Normal", "XYZ"),
                 "confidence": confidence, "image": final @ LUMINANCE,
                 "reference_step": _local_step(reference @ LUMINANCE), "faded": difference}
    strengths = []
    for axis in (0, 1):  # vertical, then horizontal neighbours
        a, b = ({name: array.take(range(start, array.shape[axis] - 1 + start), axis)
                 for name, array in per_pixel.items()} for start in (0, 1))
        close = np.abs(a["depth"] - b["depth"]) < 0.02 * np.minimum(a["depth"], b["depth"])
        same_surface = a["mask"] & b["mask"] & close & ((a["normal"] * b["normal"]).sum(axis=-1) > 0.99)
        faded = np.maximum(a["faded"], b["faded"])
        visible = faded > 0.05 * np.maximum(a["image"], b["image"])
        fading = same_surface & visible & (np.abs(a["confidence"] - b["confidence"]) > 0.05)
        excess_step = np.abs(a["image"] - b["image"]) - np.maximum(a["reference_step"], b["reference_step"])
        strengths.append((np.maximum(excess_step, 0.0) / np.maximum(faded, 1e-6))[fading])
    strengths = np.concatenate(strengths)
    return float(np.percentile(strengths, 95)) if strengths.size >= 8 else None


def flicker(result):
    """Mean frame-to-frame change of the reflection layer on the reflective pixels, relative to their
    mean brightness; for scenes where nothing moves (result: evaluate_case's).

    The layer is taken as the image shows it, final - combined (the engine's
    part of a still scene is the same every frame), so a change counts as much
    as it shows.
    """
    mask = result["mask"]
    return relative_flicker(np.stack([layer[mask] for layer in result["shown_reflections"]]),
                            float(np.mean(result["image_levels"])))


def relative_flicker(shown, level):
    """Mean change from one frame to the next of SHOWN (frames x pixels), relative to LEVEL, the
    pixels' mean brightness; None where they are black."""
    return float(np.abs(np.diff(shown, axis=0)).mean() / level) if level > 1e-6 else None


def evaluate_case(frames, ssr_frame, reference_frame, brightest_seen=None):
    """Per-frame stability measurements of one case.

    ssr_frame(frame) -> (final RGB, passes channels) of our render;
    reference_frame(frame) -> (reference RGB, reflective mask). The passes'
    Combined layer is the probe/world fallback (the same EEVEE render, no SSR).
    brightest_seen(frame) -> the brightest light the frame's rays could read beyond its
    Combined layer (its guard band, its captures: the report's), or None.
    """
    result = {"frames": list(frames), "finite": True, "energy_excess": [], "seam": [],
              "flip_ssr": [], "flip_fallback": [], "shown_reflections": [], "image_levels": [],
              "mask": reference_frame(frames[0])[1]}  # flicker's region: scenes it applies to hold still
    brightest = None
    for frame in frames:
        final, passes = ssr_frame(frame)
        reference, mask = reference_frame(frame)
        result["finite"] &= bool(np.isfinite(final).all() and all(np.isfinite(c).all() for c in passes.values()))
        combined = layer_rgb(passes, "Combined")
        current = combined.reshape(-1, 3).max(axis=0)
        if brightest_seen is not None:
            current = np.maximum(current, brightest_seen(frame))
        brightest = current if brightest is None else np.maximum(brightest, current)
        result["energy_excess"].append(energy_excess(final, passes, brightest))
        result["seam"].append(seam_strength(final, passes, reference, mask))
        result["flip_ssr"].append(flip_error(reference, final, mask))
        result["flip_fallback"].append(flip_error(reference, combined, mask))
        result["shown_reflections"].append((final - combined) @ LUMINANCE)
        result["image_levels"].append(float((final @ LUMINANCE)[result["mask"]].mean()))
    return result


def summarise_case(result):
    """The numbers of one case for bench.json (no images)."""
    seams = [seam for seam in result["seam"] if seam is not None]
    margins = [ours - fallback for ours, fallback in zip(result["flip_ssr"], result["flip_fallback"])
               if ours is not None]
    energy = max(result["energy_excess"])
    return {
        "finite": result["finite"],
        "energy_excess_max": energy if np.isfinite(energy) else None,  # NaN pixels: see "finite"
        "seam_max": max(seams) if seams else None,
        "flip_ssr_mean": _mean(result["flip_ssr"]),
        "flip_fallback_mean": _mean(result["flip_fallback"]),
        "flip_over_fallback_max": max(margins) if margins else None,
    }


def stability_variants(motion):
    """Extra settings a case renders with: temporal off (static scenes), surface reprojection (moving camera)."""
    if motion is None:
        return {"temporal off": replace(ChainSettings(), use_temporal=False)}
    if motion == "camera":
        return {f"reproject {mode}": replace(ChainSettings(), temporal_reprojection=mode)
                for mode in ("hit", "surface")}
    return {}


def run_stability(options, work_dir, log=print):
    """Every stability case over STABILITY_FRAMES: the measurements above, per case."""
    frames = list(range(STABILITY_FRAMES[0], STABILITY_FRAMES[1] + 1))
    results = {}
    for case, motion in stability_cases().items():
        path = os.path.join(SCENES_DIR, f"{case}.py")
        scene = load_scene(path)
        references = {frame: render_reference(scene, path, options.resolution, options.reference_samples, frame,
                                              options.cache_dir, log)
                      for frame in (frames if motion else frames[:1])}

        def reference_frame(frame):
            reference = references[frame if motion else frames[0]]
            return reference.image, reference.mask

        measured = {}

        def measure(settings):
            if settings not in measured:  # a variant may equal the defaults
                folder = os.path.join(work_dir, case, str(len(measured)))
                run_render(scene, path, RenderRequest(out_dir=folder, method="ssr", resolution=options.resolution,
                                                      frames=STABILITY_FRAMES, samples=options.eevee_samples,
                                                      settings=settings), log=lambda _: None)
                with open(os.path.join(folder, "report.json"), encoding="utf-8") as stream:
                    seen = {entry["frame"]: np.array(entry.get("brightest_seen", [0.0, 0.0, 0.0]))
                            for entry in json.load(stream)["frames"]}
                measured[settings] = evaluate_case(frames, render_folder_frame(folder), reference_frame,
                                                   seen.get)
            return measured[settings]

        default = measure(ChainSettings())
        summary = dict(summarise_case(default), motion=motion)
        variants = {label: measure(settings) for label, settings in stability_variants(motion).items()}
        if motion is None:
            summary["flicker"] = flicker(default)
            if "temporal off" in variants:
                summary["flicker_temporal_off"] = flicker(variants["temporal off"])
        for mode in ("hit", "surface"):
            if f"reproject {mode}" in variants:
                # frame 1 has no history: ghosting shows from the second frame on
                summary[f"ghosting_flip_{mode}"] = _mean(variants[f"reproject {mode}"]["flip_ssr"][1:])
        results[case] = summary
        log(f"stability {case}: " + ", ".join(f"{k} {_format(v)}" for k, v in summary.items() if k != "motion"))
    return results
