"""Speed against accuracy: `python -m ssr_addon bench [--scenes ...] [--resolution WxH] --out DIR`.

Every contender renders the same scenes: no SSR (probe/world reflections),
EEVEE's own screen-space ray tracing at its default and at its highest
quality, and this project at each preset and with each stage switched off in
turn. Each is scored against a Cycles path trace (rendered once, cached by a
hash of scene, resolution and settings) and timed per frame and, for ours,
per stage, also as a multiple of a full-screen copy pass timed in the same
run. The stability cases (test_scenes/stability_*.py) run over short
animations and are measured with the functions tests/test_stability.py
asserts on, so the bench's numbers and the tests' verdicts cannot drift apart.

A development tool: flip-evaluator, scikit-image and matplotlib are dev
dependencies, imported only inside the functions that use them.
"""
import ast
import csv
import fnmatch
import hashlib
import json
import os
import shlex
import statistics
import tempfile
from dataclasses import dataclass, field, fields, replace

import bpy
import numpy as np
import OpenImageIO as oiio

from .chain import ChainState
from .errors import SSRError
from .gpu_backend import StageTimer, describe_gpu, empty_texture, ensure_backend
from .outputs import prepare_output_folder, rewrite_readme_block, write_exr, write_json, written_together
from .overrides import TemporaryChanges
from .passes import lamp_world_for_run
from .params import PRESETS, STAGE_TOGGLES, ChainSettings
from .render_job import RenderRequest, parse_resolution, render_frame, run_render
from .scene_io import load_scene
from .shaders import get_pass

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES_DIR = os.path.join(REPO, "test_scenes")
DEFAULT_SCENES = ("mirror_floor", "glossy_corridor", "rough_spheres")
DEFAULT_RESOLUTION = (160, 90)
DEFAULT_FRAMES = 3
DEFAULT_CACHE = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"),
                             "stochastic-ssr", "references")
# Two Cycles renders of half the samples each, with different seeds: their mean
# is the reference and their difference measures the reference's own noise.
REFERENCE_SAMPLES = 2048
# EEVEE samples of every contender's render, whatever the scene says, so contenders and runs compare.
EEVEE_SAMPLES = 16
REFERENCE_SEEDS = (0, 1)
CACHE_FORMAT = 1
COPY_PASS_REPEATS = 20
COPY_PASS_LARGE = (1600, 900)

# Reflective pixels: inside SSR's roughness range, with a specular colour large
# enough that the reflection is a visible part of the pixel.
MIN_SPECULAR_COLOR = 0.1
LUMINANCE = np.array([0.2126, 0.7152, 0.0722], np.float32)

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

ACCURACY_METRICS = ("flip_reflective", "flip_all", "mae_reflective", "psnr_reflective", "psnr_all",
                    "ssim_reflective", "ssim_all")
README_BLOCK = "bench"  # README.md's generated block: <!-- bench:start --> ... <!-- bench:end -->


@dataclass(frozen=True)
class Contender:
    name: str
    method: str
    settings: ChainSettings = field(default_factory=ChainSettings)

    def overrides(self):
        """Settings that differ from the defaults, for the record."""
        defaults = ChainSettings()
        return {f.name: getattr(self.settings, f.name) for f in fields(ChainSettings)
                if getattr(self.settings, f.name) != getattr(defaults, f.name)}


def all_contenders():
    """Every contender: the peers a user would pick instead, our presets, our stages off in turn."""
    contenders = [Contender("none", "none"), Contender("eevee-rt", "eevee-rt"),
                  Contender("eevee-rt-high", "eevee-rt-high")]
    for name, overrides in PRESETS.items():
        contenders.append(Contender(f"ssr {name}", "ssr", replace(ChainSettings(), **overrides)))
    for toggle in STAGE_TOGGLES:
        contenders.append(Contender(f"ssr {toggle}=off", "ssr", replace(ChainSettings(), **{toggle: False})))
    return contenders


def select_contenders(patterns):
    contenders = all_contenders()
    if not patterns:
        return contenders
    chosen = [c for c in contenders if any(fnmatch.fnmatchcase(c.name, p) for p in patterns)]
    if not chosen:
        raise SSRError(f"--contenders {' '.join(patterns)}: matches none of {', '.join(c.name for c in contenders)}")
    return chosen


def resolve_scene(name):
    """A scene name from test_scenes/ or a path to a .blend or .py scene."""
    path = name if os.path.splitext(name)[1] else os.path.join(SCENES_DIR, f"{name}.py")
    if not os.path.isfile(path):
        raise SSRError(f"scene {name!r} not found (neither a file nor a scene in {SCENES_DIR})")
    return os.path.abspath(path)


def scene_label(path):
    return os.path.splitext(os.path.basename(path))[0]


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


# --- reading frames back ---------------------------------------------------------------

def read_channels(path):
    """{channel name: (H, W) float32} of a single-part EXR as run_render writes it."""
    source = oiio.ImageInput.open(path)
    if source is None:
        raise SSRError(f"cannot read {path}: {oiio.geterror()}")
    try:
        spec = source.spec()
        pixels = source.read_image(0, 0, 0, spec.nchannels, "float")
    finally:
        source.close()
    return {name: np.asarray(pixels[..., index]) for index, name in enumerate(spec.channelnames)}


def layer_rgb(channels, layer=None, components="RGB"):
    prefix = f"{layer}." if layer else ""
    return np.stack([channels[f"{prefix}{c}"] for c in components], axis=-1)


def render_folder_frame(folder):
    """frame -> (final RGB, passes channels) of a run_render output folder."""
    def frame_images(frame):
        stem = os.path.join(folder, f"frame_{frame:04d}")
        return layer_rgb(read_channels(stem + ".exr")), read_channels(stem + ".passes.exr")
    return frame_images


# --- accuracy -------------------------------------------------------------------------

def reflective_mask(roughness, specular_color):
    return (roughness <= ChainSettings().max_roughness) & (specular_color.max(axis=-1) >= MIN_SPECULAR_COLOR)


def display(linear):
    """Scene-linear RGB to [0, 1]: Reinhard tone map, then the sRGB transfer curve.

    PSNR, SSIM and the contact sheet use it; FLIP takes the linear images (HDR-FLIP).
    """
    mapped = np.maximum(linear, 0.0) / (1.0 + np.maximum(linear, 0.0))
    return np.where(mapped <= 0.0031308, 12.92 * mapped, 1.055 * np.power(mapped, 1 / 2.4) - 0.055)


def flip_map(reference, image):
    """Per-pixel HDR-FLIP error in [0, 1]; exposures follow the reference."""
    import flip_evaluator
    error, _, _ = flip_evaluator.evaluate(np.ascontiguousarray(np.maximum(reference, 0), np.float32),
                                          np.ascontiguousarray(np.maximum(image, 0), np.float32),
                                          "HDR", applyMagma=False)
    return error[..., 0]


def flip_error(reference, image, mask):
    """Mean FLIP over MASK; None where the mask is empty."""
    return float(flip_map(reference, image)[mask].mean()) if mask.any() else None


def relative_mae(reference, image, mask):
    """Mean absolute error over MASK relative to the reference's mean there; None where empty."""
    if not mask.any():
        return None
    return float(np.abs(image[mask] - reference[mask]).mean() / max(np.abs(reference[mask]).mean(), 1e-6))


def accuracy(reference, image, mask):
    """FLIP, PSNR and SSIM against the reference, on the reflective pixels and the whole image, and
    the relative mean absolute error (linear radiance) on the reflective pixels."""
    from skimage.metrics import structural_similarity
    error = flip_map(reference, image)
    shown_reference, shown = display(reference), display(image)
    _, ssim = structural_similarity(shown_reference, shown, channel_axis=-1, data_range=1.0, full=True,
                                    gaussian_weights=True, sigma=1.5, use_sample_covariance=False)
    squared = ((shown_reference - shown) ** 2).mean(axis=-1)

    def psnr(selection):
        return float(10 * np.log10(1.0 / max(squared[selection].mean(), 1e-12)))
    everywhere = np.ones_like(mask)
    scores = {"mae_reflective": relative_mae(reference, image, mask)}
    for region, selection in (("reflective", mask), ("all", everywhere)):
        empty = not selection.any()
        scores[f"flip_{region}"] = None if empty else float(error[selection].mean())
        scores[f"psnr_{region}"] = None if empty else psnr(selection)
        scores[f"ssim_{region}"] = None if empty else float(ssim.mean(axis=-1)[selection].mean())
    return scores, error


# --- the Cycles reference, cached -------------------------------------------------------

def _file_digest(digest, path):
    with open(path, "rb") as stream:
        digest.update(stream.read())


def scene_digest(path):
    """Hash of a scene file and, for a builder script, the sibling modules it imports."""
    digest = hashlib.sha256()
    _file_digest(digest, path)
    if path.endswith(".py"):
        with open(path, encoding="utf-8") as source:
            tree = ast.parse(source.read())
        modules = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
        modules |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and node.module}
        for module in sorted(modules):
            sibling = os.path.join(os.path.dirname(path), f"{module}.py")
            if os.path.isfile(sibling):
                _file_digest(digest, sibling)
    return digest.hexdigest()


def reference_key(scene_path, resolution, samples, frame):
    """Everything the reference depends on: the scene, how it is rendered, where and when."""
    digest = hashlib.sha256()
    _file_digest(digest, os.path.join(os.path.dirname(__file__), "passes.py"))  # the render configuration
    digest.update(json.dumps({"format": CACHE_FORMAT, "scene": scene_digest(scene_path),
                              "resolution": list(resolution), "samples": samples, "frame": frame,
                              "seeds": REFERENCE_SEEDS, "blender": bpy.app.version_string}).encode())
    return digest.hexdigest()[:24]


@dataclass
class Reference:
    image: np.ndarray           # (H, W, 3) scene linear
    roughness: np.ndarray
    specular_color: np.ndarray
    info: dict                  # samples, render milliseconds, noise, cached

    @property
    def mask(self):
        return reflective_mask(self.roughness, self.specular_color)


def render_reference(scene, scene_path, resolution, samples, frame, cache_dir, log=print):
    """The Cycles reference of FRAME, from the cache or rendered once and stored there."""
    key = reference_key(scene_path, resolution, samples, frame)
    image_path, info_path = (os.path.join(cache_dir, f"{key}.{ext}") for ext in ("exr", "json"))
    if os.path.isfile(image_path) and os.path.isfile(info_path):
        with open(info_path, encoding="utf-8") as stream:
            info = dict(json.load(stream), cached=True)
        channels = read_channels(image_path)
        return Reference(layer_rgb(channels, "Reference"), channels["Roughness.V"],
                         layer_rgb(channels, "Specular Color"), info)
    prepare_output_folder(cache_dir)
    scene.frame_set(frame)
    halves, milliseconds = [], 0.0
    for seed in REFERENCE_SEEDS:
        with TemporaryChanges() as changes:
            changes.set(scene.cycles, "seed", seed)
            images, timer = render_frame(scene, RenderRequest(out_dir=cache_dir, method="cycles", resolution=resolution,
                                                              samples=samples // len(REFERENCE_SEEDS)))
        halves.append(images)
        milliseconds += sum(timer.milliseconds.values())
    first, second = (half["final"][..., :3] for half in halves)
    passes = halves[0]["passes"]
    image = (first + second) / 2
    info = {
        "samples": samples, "frame": frame, "render_ms": round(milliseconds, 1),
        # The mean of two halves has half the variance of either: its noise is |a - b| / 2.
        "noise_rmse": float(np.sqrt(np.mean((first - second) ** 2)) / 2),
        "noise_flip_reflective": flip_error(first, second, reflective_mask(passes.roughness, passes.specular_color)),
    }
    channels = {}
    for layer, array in (("Reference", image), ("Specular Color", passes.specular_color)):
        channels.update({f"{layer}.{c}": array[..., index] for index, c in enumerate("RGB")})
    channels["Roughness.V"] = passes.roughness
    with written_together([image_path]) as (partial,):
        write_exr(partial, channels)
    write_json(info_path, info)  # last: an entry counts as cached once both files are there
    log(f"reference {scene_label(scene_path)} frame {frame}: {samples} samples, {milliseconds / 1000:.1f} s")
    return Reference(image, passes.roughness, passes.specular_color, dict(info, cached=False))


# --- speed ----------------------------------------------------------------------------

def copy_pass_ms(size, repeats=COPY_PASS_REPEATS):
    """Median milliseconds of the full-screen copy pass (one RGBA32F texelFetch per pixel) at SIZE."""
    ensure_backend()
    source, target = empty_texture(size), empty_texture(size)
    copy = get_pass("copy")
    samples = []
    for repeat in range(repeats + 1):
        timer = StageTimer()
        timer.lap("idle", target)  # start with the GPU idle
        copy.draw([target], samplers=(("source_tx", source),))
        timer.lap("copy", target)
        if repeat:  # the first draw warms up (allocation, shader compilation)
            samples.append(timer.milliseconds["copy"])
    return statistics.median(samples)


def pareto_front(points):
    """Names of the points no other point beats on both time and error (lower is better)."""
    front = []
    for name, (time_ms, error) in points.items():
        dominated = any(other_time <= time_ms and other_error <= error and (other_time, other_error) != (time_ms, error)
                        for other, (other_time, other_error) in points.items() if other != name)
        if not dominated:
            front.append(name)
    return sorted(front, key=lambda name: points[name][0])


# --- stability measurements (asserted by tests/test_stability.py) -------------------------

def energy_excess(final, passes, brightest):
    """How far the frame exceeds the energy bound, as a fraction of the brightest radiance B.

    The composite computes final = combined + FG * (c R) - c * s * I, with c R
    the premultiplied "SSR Reflection" layer (c the confidence), s the specular
    colour and I the indirect specular (probe/world) light; so the light SSR
    put in is added = final - combined + c s I = FG * c R (before the
    composite's clamp at 0). SSR only fetches, filters and accumulates radiance
    that this or an earlier frame showed, so R <= B (per channel, B the
    brightest Combined pixel so far), and a surface reflects at most what
    reaches it (FG <= 1). So per pixel and channel:
        c R <= c B   and   0 <= added <= c R.
    At most ENERGY_TOLERANCE means it holds (the composite runs in 32-bit floats).
    """
    confidence = passes["SSR Confidence.V"][..., None]
    probe = layer_rgb(passes, "Specular Color") * layer_rgb(passes, "Specular Indirect")
    added = final - layer_rgb(passes, "Combined") + confidence * probe
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
    shown = np.stack([layer[mask] for layer in result["shown_reflections"]])
    level = float(np.mean(result["image_levels"]))
    return float(np.abs(np.diff(shown, axis=0)).mean() / level) if level > 1e-6 else None


def evaluate_case(frames, ssr_frame, reference_frame):
    """Per-frame stability measurements of one case.

    ssr_frame(frame) -> (final RGB, passes channels) of our render;
    reference_frame(frame) -> (reference RGB, reflective mask). The passes'
    Combined layer is the probe/world fallback (the same EEVEE render, no SSR).
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


def _mean(values):
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


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
                measured[settings] = evaluate_case(frames, render_folder_frame(folder), reference_frame)
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


# --- the run --------------------------------------------------------------------------

@dataclass
class BenchOptions:
    scenes: list
    out_dir: str
    resolution: tuple = DEFAULT_RESOLUTION
    frames: int = DEFAULT_FRAMES
    eevee_samples: int = EEVEE_SAMPLES   # every EEVEE render's samples
    reference_samples: int = REFERENCE_SAMPLES
    cache_dir: str = DEFAULT_CACHE
    contenders: list = None
    stability: bool = True
    readme: str = None


def require_dev_dependencies():
    missing = []
    for module in ("flip_evaluator", "matplotlib", "skimage"):
        try:
            __import__(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise SSRError(f"the bench needs the dev dependencies ({', '.join(missing)} missing): "
                       f"pip install -e '.[dev]'")


def run_contenders(scene, contenders, options):
    """Render every contender for options.frames frames, taking turns frame by frame.

    Taking turns spreads any change in the machine's load over all contenders
    alike. Each contender keeps its own ChainState and draws each frame's
    random numbers as run_render does, so its frames are those of a still
    animation, with temporal history. Returns {name: (final image of the last
    frame, {stage: milliseconds})}, each stage's time the fastest over the
    frames after the first (other processes only ever add time; a first frame
    accumulates a still's iterations, and the process's first render is
    quicker than any later one).
    """
    states = {contender.name: ChainState() for contender in contenders}
    finals, laps = {}, {contender.name: [] for contender in contenders}
    with lamp_world_for_run():  # as a batch render keeps it
        for frame in range(scene.frame_current, scene.frame_current + options.frames):
            for contender in contenders:
                state = states[contender.name]
                state.begin_frame(frame)
                request = RenderRequest(out_dir=options.out_dir, method=contender.method,
                                        resolution=options.resolution, samples=options.eevee_samples,
                                        settings=contender.settings)
                images, timer = render_frame(scene, request, state)
                finals[contender.name] = images["final"][..., :3]
                laps[contender.name].append(timer.milliseconds)
    results = {}
    for name, frames in laps.items():
        timed = frames[1:] or frames
        results[name] = (finals[name], {stage: min(frame.get(stage, 0.0) for frame in timed) for stage in frames[0]})
    return results


def run_bench(options, log=print):
    """Run the whole bench into options.out_dir; returns the bench.json data."""
    require_dev_dependencies()
    if options.frames < 1:
        raise SSRError(f"--frames must be at least 1, got {options.frames}")
    if options.eevee_samples < 1:
        raise SSRError(f"--samples must be at least 1, got {options.eevee_samples}")
    if options.reference_samples < len(REFERENCE_SEEDS):
        raise SSRError(f"--reference-samples must be at least {len(REFERENCE_SEEDS)}")
    if options.readme and not os.path.isfile(options.readme):
        raise SSRError(f"--readme {options.readme}: no such file")
    scene_paths = [resolve_scene(name) for name in options.scenes]
    contenders = select_contenders(options.contenders)
    prepare_output_folder(options.out_dir)
    ensure_backend()
    copy_ms = {_size_label(size): copy_pass_ms(size) for size in (options.resolution, COPY_PASS_LARGE)}
    copy_here = copy_ms[_size_label(options.resolution)]
    log("copy pass: " + ", ".join(f"{size} {ms:.3f} ms" for size, ms in copy_ms.items()))

    rows, sheet, references = [], {}, {}
    for scene_path in scene_paths:
        label = scene_label(scene_path)
        scene = load_scene(scene_path)
        reference = render_reference(scene, scene_path, options.resolution, options.reference_samples,
                                     scene.frame_current, options.cache_dir, log)
        references[label] = reference.info
        sheet[label] = {"reference": (reference.image, reference.mask)}
        rendered = run_contenders(scene, contenders, options)
        for contender in contenders:
            final, stages = rendered[contender.name]
            frame_ms = sum(stages.values())
            addon_ms = frame_ms - stages.get("render", 0.0)  # everything but the engine's own render
            scores, error = accuracy(reference.image, final, reference.mask)
            sheet[label][contender.name] = (final, error)
            rows.append({"scene": label, "contender": contender.name, "method": contender.method,
                         "frame_ms": frame_ms, "addon_ms": addon_ms, "frame_x_copy": frame_ms / copy_here, **scores,
                         "stages_ms": stages, "stages_x_copy": {s: ms / copy_here for s, ms in stages.items()}})
            log(f"{label} / {contender.name}: {frame_ms:.0f} ms, FLIP reflective {_format(scores['flip_reflective'])}")
        _warn_if_reference_noisy(label, reference.info, [r for r in rows if r["scene"] == label], log)

    summary = summarise_contenders(contenders, rows, copy_here)
    report = {
        "blender": bpy.app.version_string, "gpu": describe_gpu(), "resolution": list(options.resolution),
        "scenes": [scene_label(p) for p in scene_paths], "frames_per_contender": options.frames,
        "contender_patterns": options.contenders,
        "eevee_samples": options.eevee_samples,
        "timing": "contenders take turns frame by frame; each stage's fastest time over the frames after the "
                  "first (the least disturbed by other processes); a frame's time is the sum of its stages, "
                  "render_frame's StageTimer laps; the engine's render is the 'render' stage, the lamp-only "
                  "render SSR needs in scenes with lamps the 'lamp_split' stage (the add-on's share: addon_ms)",
        "copy_pass_ms": copy_ms, "copy_pass_repeats": COPY_PASS_REPEATS,
        "reflective_mask": {"max_roughness": ChainSettings().max_roughness, "min_specular_color": MIN_SPECULAR_COLOR},
        "reference": {"engine": "cycles", "samples": options.reference_samples, "seeds": list(REFERENCE_SEEDS),
                      "per_scene": references},
        "contenders": summary, "results": rows,
    }
    if options.stability:
        with tempfile.TemporaryDirectory(prefix="ssr_stability_") as work_dir:
            report["stability"] = {
                "frames": list(STABILITY_FRAMES),
                "limits": {"fallback_margin_flip": FALLBACK_MARGIN, "seam": SEAM_LIMIT, "flicker": FLICKER_LIMIT,
                           "energy_tolerance": ENERGY_TOLERANCE},
                "cases": run_stability(options, work_dir, log),
            }
    write_outputs(report, sheet, options.out_dir)
    if options.readme:
        update_readme(options.readme, report, options.out_dir)
    return report


# The goal: our balanced preset's error on reflective pixels at most this share of
# EEVEE's own screen-space ray tracing's, on every scene.
VERSUS_EEVEE_GOAL = 0.8


def versus_eevee(rows, ours="ssr balanced", theirs="eevee-rt"):
    """Per scene: (FLIP ours, FLIP theirs, rel. MAE ours, rel. MAE theirs) on reflective pixels."""
    by_key = {(row["scene"], row["contender"]): row for row in rows}
    table = {}
    for scene in dict.fromkeys(row["scene"] for row in rows):
        mine, other = by_key.get((scene, ours)), by_key.get((scene, theirs))
        if mine and other and None not in (mine["flip_reflective"], other["flip_reflective"]):
            table[scene] = (mine["flip_reflective"], other["flip_reflective"],
                            mine["mae_reflective"], other["mae_reflective"])
    return table


def _versus_eevee_lines(report):
    table = versus_eevee(report["results"])
    if not table:
        return []
    lines = ["", f"Per scene, `ssr balanced` against EEVEE's screen-space ray tracing (`eevee-rt`) on the "
                 f"reflective pixels; the goal is a ratio of at most {VERSUS_EEVEE_GOAL}:", "",
             "| scene | FLIP ours | FLIP eevee-rt | ratio | rel. MAE ours | rel. MAE eevee-rt | ratio |",
             "|---|---:|---:|---:|---:|---:|---:|"]
    for scene, (flip_ours, flip_eevee, mae_ours, mae_eevee) in table.items():
        lines.append(f"| {scene} | {flip_ours:.4f} | {flip_eevee:.4f} | {flip_ours / flip_eevee:.2f} | "
                     f"{mae_ours:.4f} | {mae_eevee:.4f} | {mae_ours / mae_eevee:.2f} |")
    return lines


def summarise_contenders(contenders, rows, copy_ms):
    """One entry per contender: its means over the scenes and whether it is on the Pareto front."""
    summary = []
    for contender in contenders:
        mine = [row for row in rows if row["contender"] == contender.name]
        stages = {stage: float(np.mean([row["stages_ms"].get(stage, 0.0) for row in mine]))
                  for stage in mine[0]["stages_ms"]}
        entry = {"name": contender.name, "method": contender.method, "settings": contender.overrides(),
                 "frame_ms": float(np.mean([row["frame_ms"] for row in mine])),
                 "addon_ms": float(np.mean([row["addon_ms"] for row in mine])),
                 "stages_ms": stages, "stages_x_copy": {s: ms / copy_ms for s, ms in stages.items()}}
        entry["frame_x_copy"] = entry["frame_ms"] / copy_ms
        for metric in ACCURACY_METRICS:
            entry[metric] = _mean([row[metric] for row in mine])
        summary.append(entry)
    scored = {e["name"]: (e["frame_ms"], e["flip_reflective"]) for e in summary if e["flip_reflective"] is not None}
    front = pareto_front(scored)
    for entry in summary:
        entry["pareto"] = entry["name"] in front
    return summary


def _warn_if_reference_noisy(label, info, rows, log):
    errors = [row["flip_reflective"] for row in rows if row["flip_reflective"] is not None]
    noise = info.get("noise_flip_reflective")
    if errors and noise is not None and noise > min(errors) / 3:
        log(f"warning: {label}: the reference's own noise (FLIP {noise:.4f} between its halves) is not far below "
            f"the smallest error measured ({min(errors):.4f}); raise --reference-samples")


def _size_label(size):
    return f"{size[0]}x{size[1]}"


def _format(value):
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "NO"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


# --- outputs --------------------------------------------------------------------------

CSV_METRICS = ("frame_ms", "addon_ms", "frame_x_copy", *ACCURACY_METRICS)


def write_outputs(report, sheet, out_dir):
    write_json(os.path.join(out_dir, "bench.json"), report)
    write_csv(os.path.join(out_dir, "bench.csv"), report)
    chart_speed_vs_accuracy(report, os.path.join(out_dir, "speed_vs_accuracy.png"))
    contact_sheet(sheet, os.path.join(out_dir, "contact_sheet.png"))
    if "stability" in report:
        chart_stability(report["stability"], os.path.join(out_dir, "stability.png"))


def write_csv(path, report):
    """One row per scene and contender, then one per contender over all scenes (scene "mean")."""
    stages = list(dict.fromkeys(stage for row in report["results"] for stage in row["stages_ms"]))
    header = ["scene", "contender", "method", *CSV_METRICS, "pareto",
              *(f"{stage}_ms" for stage in stages), *(f"{stage}_x_copy" for stage in stages)]
    pareto = {entry["name"]: entry["pareto"] for entry in report["contenders"]}
    lines = [dict(row, pareto=pareto[row["contender"]]) for row in report["results"]]
    lines += [dict(entry, scene="mean", contender=entry["name"]) for entry in report["contenders"]]
    with written_together([path]) as (partial,), open(partial, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        for line in lines:
            writer.writerow([line["scene"], line["contender"], line["method"],
                             *(_csv_value(line[m]) for m in CSV_METRICS), line["pareto"],
                             *(_csv_value(line["stages_ms"].get(s)) for s in stages),
                             *(_csv_value(line["stages_x_copy"].get(s)) for s in stages)])


def _csv_value(value):
    return "" if value is None else f"{value:.6g}"


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot


def _save_figure(figure, path, palette=False):
    """Write FIGURE as a PNG, atomically; PALETTE: 256 colours (a contact sheet shrinks about threefold)."""
    with written_together([path]) as (partial,):
        if palette:
            from PIL import Image  # matplotlib's own image library
            figure.canvas.draw()
            pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]
            Image.fromarray(pixels).quantize(colors=256).save(partial, format="PNG", optimize=True)
        else:
            figure.savefig(partial, format="png")
    _pyplot().close(figure)


def chart_speed_vs_accuracy(report, path):
    """Milliseconds per frame against FLIP on reflective pixels, one point per contender, Pareto front joined."""
    pyplot = _pyplot()
    entries = [e for e in report["contenders"] if e["flip_reflective"] is not None]
    figure, axes = pyplot.subplots(figsize=(9, 4.5), dpi=100)
    # Points carry numbers, named beside the plot: the names would overlap where points crowd.
    for number, entry in enumerate(entries, 1):
        colour = "tab:red" if entry["pareto"] else "tab:blue"
        axes.scatter(entry["frame_ms"], entry["flip_reflective"], color=colour, zorder=3,
                     label=f"{number}  {entry['name']}")
        axes.annotate(str(number), (entry["frame_ms"], entry["flip_reflective"]), fontsize=7,
                      xytext=(4, 3), textcoords="offset points")
    front = sorted((e for e in entries if e["pareto"]), key=lambda e: e["frame_ms"])
    axes.step([e["frame_ms"] for e in front], [e["flip_reflective"] for e in front], where="post",
              color="tab:red", linewidth=1, label="Pareto front")
    reference_ms = [info["render_ms"] for info in report["reference"]["per_scene"].values()]
    axes.axvline(np.mean(reference_ms), color="grey", linestyle="--", linewidth=1,
                 label=f"Cycles reference ({report['reference']['samples']} spp, error 0 by definition)")
    axes.set_xscale("log")
    axes.set_xlabel("wall time per frame, whole method (ms, log scale)")
    axes.set_ylabel("mean FLIP on reflective pixels (lower is better)")
    width, height = report["resolution"]
    axes.set_title(f"Speed vs accuracy at {width}x{height}, mean over {', '.join(report['scenes'])}", fontsize=9)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    figure.tight_layout()
    _save_figure(figure, path)


def contact_sheet(sheet, path):
    """Every contender beside the reference, per scene: the image and its FLIP error map.

    The reference row shows the reflective-pixel mask in place of an error map.
    """
    pyplot = _pyplot()
    from matplotlib import colormaps
    scenes = list(sheet)
    names = list(sheet[scenes[0]])
    height, width = sheet[scenes[0]]["reference"][0].shape[:2]
    dpi = 100
    label_inches, tile_inches = 2.0, (width / dpi, height / dpi)
    figure = pyplot.figure(figsize=(label_inches + 2 * len(scenes) * tile_inches[0],
                                    (len(names) + 0.3) * tile_inches[1]), dpi=dpi)
    for row, name in enumerate(names):
        for column, scene in enumerate(scenes):
            image, second = sheet[scene][name]
            tiles = (display(image), np.repeat(second[..., None], 3, -1).astype(np.float32) if name == "reference"
                     else colormaps["magma"](np.clip(second, 0, 1))[..., :3])
            for offset, tile in enumerate(tiles):
                left = (label_inches + (2 * column + offset) * tile_inches[0]) / figure.get_figwidth()
                bottom = 1 - (row + 1.3) * tile_inches[1] / figure.get_figheight()
                axes = figure.add_axes((left, bottom, tile_inches[0] / figure.get_figwidth(),
                                        tile_inches[1] / figure.get_figheight()))
                axes.imshow(tile, interpolation="nearest")
                axes.set_axis_off()
                if row == 0:
                    axes.set_title(f"{scene}: {('image', 'mask / FLIP')[offset]}", fontsize=6, pad=2)
        figure.text(0.01, 1 - (row + 0.8) * tile_inches[1] / figure.get_figheight(), name, fontsize=7,
                    va="center")
    _save_figure(figure, path, palette=True)


def chart_stability(stability, path):
    """Per case: error against the fallback's, seam strength, flicker and ghosting, with the tested limits."""
    pyplot = _pyplot()
    cases = stability["cases"]
    names = [case.removeprefix("stability_") for case in cases]
    positions = np.arange(len(cases))
    figure, axes = pyplot.subplots(2, 2, figsize=(10, 6), dpi=80)

    def values(key):
        return [np.nan if cases[c].get(key) is None else cases[c][key] for c in cases]
    panel = axes[0, 0]
    panel.bar(positions - 0.2, values("flip_ssr_mean"), 0.4, label="ssr")
    panel.bar(positions + 0.2, values("flip_fallback_mean"), 0.4, label="probe/world fallback")
    panel.set_title("mean FLIP on reflective pixels vs Cycles", fontsize=9)
    panel.legend(fontsize=7)
    panel = axes[0, 1]
    panel.bar(positions, values("seam_max"), 0.6)
    panel.axhline(SEAM_LIMIT, color="tab:red", linestyle="--", linewidth=1, label="test limit")
    panel.set_title("seam strength (0 smooth fade, 1 one-pixel cut)", fontsize=9)
    panel.legend(fontsize=7)
    panel = axes[1, 0]
    panel.bar(positions - 0.2, values("flicker"), 0.4, label="default")
    panel.bar(positions + 0.2, values("flicker_temporal_off"), 0.4, label="temporal off")
    panel.axhline(FLICKER_LIMIT, color="tab:red", linestyle="--", linewidth=1, label="test limit")
    panel.set_title("flicker, static scenes (relative frame-to-frame change)", fontsize=9)
    panel.legend(fontsize=7)
    panel = axes[1, 1]
    panel.bar(positions - 0.2, values("ghosting_flip_hit"), 0.4, label="reproject hit point")
    panel.bar(positions + 0.2, values("ghosting_flip_surface"), 0.4, label="reproject surface point")
    panel.set_title("ghosting: FLIP vs per-frame references, frames 2+", fontsize=9)
    panel.legend(fontsize=7)
    for panel in axes.ravel():
        panel.set_xticks(positions, names, fontsize=7, rotation=20)
        panel.tick_params(axis="y", labelsize=7)
    figure.tight_layout()
    _save_figure(figure, path)


def _contenders_argument(report):
    patterns = report.get("contender_patterns")
    return " --contenders " + " ".join(shlex.quote(p) for p in patterns) if patterns else ""


def readme_block(report, out_dir, readme_dir):
    """Markdown for the README: the chart, the contender table and the stability table."""
    folder = os.path.relpath(out_dir, readme_dir).replace(os.sep, "/")
    width, height = report["resolution"]
    copy_ms = report["copy_pass_ms"][f"{width}x{height}"]
    lines = [
        f"Latest run: `python -m ssr_addon bench --scenes {' '.join(report['scenes'])} "
        f"--resolution {width}x{height} --out {folder} --readme README.md{_contenders_argument(report)}` on "
        f"Blender {report['blender']}, "
        f"{report['gpu']['renderer']}: a software GPU, so every engine render is slow. Reference: Cycles, "
        f"{report['reference']['samples']} samples; EEVEE: {report['eevee_samples']} samples. Time: wall time "
        f"per frame of the whole method, engine render included; *add-on ms*: our own share of it, everything "
        f"but the engine's render (in scenes with lamps SSR needs a second, lamp-only render: `lamp_split`, "
        f"counted here); the contenders take turns over {report['frames_per_contender']} frames and each "
        f"stage counts its fastest after the first; ×copy: as a multiple of a "
        f"full-screen copy pass ({copy_ms:.3f} ms here, "
        f"{report['copy_pass_ms'][_size_label(COPY_PASS_LARGE)]:.3f} ms at 1600x900). Errors: mean over the "
        f"scenes, on the last frame; *refl.* is the reflective pixels (roughness ≤ "
        f"{report['reflective_mask']['max_roughness']}, specular colour ≥ {MIN_SPECULAR_COLOR}).",
        "",
        f"![speed vs accuracy]({folder}/speed_vs_accuracy.png)",
        "",
        "| contender | ms/frame | add-on ms | ×copy | FLIP refl. | rel. MAE refl. | FLIP all | PSNR refl. | SSIM refl. "
        "| Pareto |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|:-:|",
    ]
    for entry in report["contenders"]:
        lines.append(f"| {entry['name']} | {entry['frame_ms']:.0f} | {entry['addon_ms']:.0f} | "
                     f"{entry['frame_x_copy']:.0f} | "
                     f"{_cell(entry['flip_reflective'], 4)} | {_cell(entry['mae_reflective'], 4)} | "
                     f"{_cell(entry['flip_all'], 4)} | "
                     f"{_cell(entry['psnr_reflective'], 2)} | {_cell(entry['ssim_reflective'], 3)} | "
                     f"{'✓' if entry['pareto'] else ''} |")
    lines += _versus_eevee_lines(report)
    ours = [e for e in report["contenders"] if e["method"] == "ssr"]
    if ours:
        stages = [s for s in ours[0]["stages_ms"] if s != "render"]
        lines += ["", "Stages of ours (ms, ×copy):", "",
                  "| contender | " + " | ".join(stages) + " |", "|---|" + "---:|" * len(stages)]
        for entry in ours:
            lines.append(f"| {entry['name']} | " + " | ".join(
                f"{entry['stages_ms'].get(s, 0):.2f} ({entry['stages_x_copy'].get(s, 0):.1f})" for s in stages) + " |")
    if "stability" in report:
        limits = report["stability"]["limits"]
        lines += ["", f"Stability cases over frames {'-'.join(map(str, report['stability']['frames']))}, with the "
                      f"limits the tests assert: FLIP at most the fallback's + {limits['fallback_margin_flip']}, "
                      f"energy excess at most {limits['energy_tolerance']}, seam below {limits['seam']}, "
                      f"flicker below {limits['flicker']}, hit-point ghosting below surface-point ghosting.",
                  "", f"![stability]({folder}/stability.png)", "",
                  "| case | motion | finite | FLIP ssr | FLIP fallback | energy excess | seam | flicker (temporal off) "
                  "| ghosting FLIP hit / surface |",
                  "|---|---|:-:|---:|---:|---:|---:|---:|---:|"]
        for case, values in report["stability"]["cases"].items():
            flicker_cell = _cell(values.get("flicker"), 4)
            if values.get("flicker_temporal_off") is not None:
                flicker_cell += f" ({_cell(values['flicker_temporal_off'], 4)})"
            ghosting = (f"{_cell(values.get('ghosting_flip_hit'), 4)} / {_cell(values.get('ghosting_flip_surface'), 4)}"
                        if values.get("ghosting_flip_hit") is not None else "-")
            lines.append(f"| {case.removeprefix('stability_')} | {values['motion'] or 'static'} | "
                         f"{'yes' if values['finite'] else '**NO**'} | {_cell(values['flip_ssr_mean'], 4)} | "
                         f"{_cell(values['flip_fallback_mean'], 4)} | {_cell(values['energy_excess_max'], 4)} | "
                         f"{_cell(values['seam_max'], 3)} | {flicker_cell} | {ghosting} |")
    lines += ["", f"Contact sheet (every contender beside the reference, FLIP error maps): "
                  f"[{folder}/contact_sheet.png]({folder}/contact_sheet.png)"]
    return "\n".join(lines)


def _cell(value, digits):
    return "-" if value is None else f"{value:.{digits}f}"


def update_readme(readme_path, report, out_dir):
    """Replace the bench block in README (adding it under '## Benchmark' if absent)."""
    readme_dir = os.path.dirname(os.path.abspath(readme_path))
    rewrite_readme_block(readme_path, README_BLOCK, readme_block(report, out_dir, readme_dir), "Benchmark")


def options_from_arguments(arguments):
    return BenchOptions(
        scenes=arguments.scenes or list(DEFAULT_SCENES), out_dir=arguments.out,
        resolution=parse_resolution(arguments.resolution) if arguments.resolution else DEFAULT_RESOLUTION,
        frames=arguments.frames, eevee_samples=arguments.samples, reference_samples=arguments.reference_samples,
        cache_dir=arguments.cache,
        contenders=arguments.contenders, stability=not arguments.no_stability, readme=arguments.readme)
