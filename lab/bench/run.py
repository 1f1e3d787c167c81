"""The whole bench run (`python -m lab bench`): options, checks, scoring every contender on every scene."""
import tempfile
from dataclasses import dataclass

import bpy

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.outputs import prepare_output_folder
from ssr_addon.batch.request import parse_resolution
from ssr_addon.blender.gpu_context import ensure_backend
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.errors import SSRError
from ssr_addon.core.gpu_backend import describe_gpu
from ssr_addon.core.settings import ChainSettings
from ..docs import require_page
from .contenders import run_contenders, select_contenders
from .metrics import MIN_SPECULAR_COLOR, _format, accuracy
from .page_block import update_page
from .references import DEFAULT_CACHE, REFERENCE_SAMPLES, REFERENCE_SEEDS, render_reference
from .report import summarise_contenders, write_outputs
from .scenes import resolve_scene, scene_label
from .speed import COPY_PASS_LARGE, COPY_PASS_REPEATS, _size_label, copy_pass_ms
from .stability import ENERGY_TOLERANCE, FALLBACK_MARGIN, FLICKER_LIMIT, SEAM_LIMIT, STABILITY_FRAMES, run_stability

DEFAULT_SCENES = ("mirror_floor", "glossy_corridor", "rough_spheres")
DEFAULT_RESOLUTION = (160, 90)
DEFAULT_FRAMES = 3
# EEVEE samples of every contender's render, whatever the scene says, so contenders and runs compare.
EEVEE_SAMPLES = 16


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
    page: str = None             # the markdown page whose bench block is rewritten


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


def run_bench(options, log=print):
    """Run the whole bench into options.out_dir; returns the bench.json data."""
    require_dev_dependencies()
    if options.frames < 1:
        raise SSRError(f"--frames must be at least 1, got {options.frames}")
    if options.eevee_samples < 1:
        raise SSRError(f"--samples must be at least 1, got {options.eevee_samples}")
    if options.reference_samples < len(REFERENCE_SEEDS):
        raise SSRError(f"--reference-samples must be at least {len(REFERENCE_SEEDS)}")
    require_page(options.page)
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
            final, stages, whole = rendered[contender.name]
            frame_ms = sum(whole.values())
            addon_ms = frame_ms - whole.get("render", 0.0)  # everything but the engine's own render
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
        "timing": "contenders take turns frame by frame; after the first frame, frames alternate between "
                  "timing each stage apart (a GPU wait after each chain stage: stages_ms) and timing the frame "
                  "as a render runs it (frame_ms, addon_ms); each stage's fastest time over its frames (the "
                  "least disturbed by other processes); a frame's time is the sum of its stages, "
                  "render_frame's StageTimer laps; the engine's render is the 'render' stage, the lamp split "
                  "SSR needs in scenes with lamps the 'lamp_split' stage (the add-on's share: addon_ms)",
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
    if options.page:
        update_page(options.page, report, options.out_dir)
    return report


def _warn_if_reference_noisy(label, info, rows, log):
    errors = [row["flip_reflective"] for row in rows if row["flip_reflective"] is not None]
    noise = info.get("noise_flip_reflective")
    if errors and noise is not None and noise > min(errors) / 3:
        log(f"warning: {label}: the reference's own noise (FLIP {noise:.4f} between its halves) is not far below "
            f"the smallest error measured ({min(errors):.4f}); raise --reference-samples")


def build_parser():
    parser = ArgumentParser(prog="python -m lab bench",
                            description="chart speed against accuracy of every method, and stability cases")
    parser.add_argument("--scenes", nargs="+", metavar="SCENE",
                        help=f"scene names in test_scenes/ or scene files (default: {' '.join(DEFAULT_SCENES)})")
    parser.add_argument("--resolution", help="WIDTHxHEIGHT (default: %dx%d)" % DEFAULT_RESOLUTION)
    parser.add_argument("--out", required=True, help="output folder for bench.json, bench.csv and the charts")
    parser.add_argument("--frames", type=int, default=DEFAULT_FRAMES,
                        help="frames each contender renders, taking turns: time is each stage's fastest "
                             "after the first, accuracy the last frame's")
    parser.add_argument("--samples", type=int, default=EEVEE_SAMPLES,
                        help="EEVEE samples per pixel of every EEVEE render, whatever the scene's (default: %(default)s)")
    parser.add_argument("--reference-samples", type=int, default=REFERENCE_SAMPLES,
                        help="Cycles samples of the reference")
    parser.add_argument("--cache", default=DEFAULT_CACHE, help="folder of cached references")
    parser.add_argument("--contenders", nargs="+", metavar="PATTERN",
                        help="only the contenders whose names match these shell patterns, e.g. 'ssr*'")
    parser.add_argument("--no-stability", action="store_true", help="skip the stability cases")
    parser.add_argument("--page", metavar="FILE", help="rewrite the bench block of this markdown page")
    return parser


def options_from_arguments(arguments):
    return BenchOptions(
        scenes=arguments.scenes or list(DEFAULT_SCENES), out_dir=arguments.out,
        resolution=parse_resolution(arguments.resolution) if arguments.resolution else DEFAULT_RESOLUTION,
        frames=arguments.frames, eevee_samples=arguments.samples, reference_samples=arguments.reference_samples,
        cache_dir=arguments.cache,
        contenders=arguments.contenders, stability=not arguments.no_stability, page=arguments.page)


def main(argv):
    return run_bench(options_from_arguments(build_parser().parse_args(argv)))
