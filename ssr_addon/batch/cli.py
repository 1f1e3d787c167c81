"""Command line: `python -m ssr_addon render SCENE --out DIR ...`, `... compare SCENE --out DIR`,
`... preview SCENE --out DIR` and `... farm SCENE --frames A-B --out DIR` (docs/cli.md).

Also reachable from the Blender binary, where SCENE may be left out to use the
.blend file Blender opened:
    blender -b shot.blend --python-expr "import ssr_addon.batch.cli as cli; cli.main()" -- render --out DIR
Errors the user can fix print one line and exit with status 2.
"""
import argparse
import os
import signal
import sys

import bpy

from ..blender.colour_management import write_display_png
from ..blender.scene_io import load_scene, require_camera
from ..core.errors import SSRError
from ..core.settings import ChainSettings
from .compare import compare_modes
from .outputs import prepare_output_folder, write_json, write_rgba_exr, written_together
from .farm import run_farm
from .preview import ORBIT_STEP_DEGREES, run_preview
from .request import DEFAULT_WARMUP_FRAMES, METHODS, RenderRequest, frame_numbers, parse_frames, parse_resolution
from .run import run_render


class ArgumentParser(argparse.ArgumentParser):
    """Bad words on the command line are an SSRError: one line, status 2."""

    def error(self, message):
        raise SSRError(message)


# The render options a farm hands on to each of its chunks: (flag, argparse keywords).
RENDER_OPTIONS = (
    ("--method", dict(default="ssr", choices=METHODS)),
    ("--engine", dict(default="eevee", choices=("eevee", "cycles"), help="engine that renders the input passes")),
    ("--resolution", dict(help="WIDTHxHEIGHT (default: the scene's)")),
    ("--samples", dict(type=int, help="EEVEE or Cycles samples per pixel (default: the scene's own)")),
    ("--set", dict(dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a chain setting, e.g. --set thickness=0.1 or --set preset=high (repeatable)")),
    ("--on-error", dict(default="stop", choices=("stop", "skip"),
                        help="a frame that fails: stop the run, or report it and go on")),
)


def _add_render_options(parser):
    for flag, keywords in RENDER_OPTIONS:
        parser.add_argument(flag, **keywords)


def _render_words(arguments):
    """RENDER_OPTIONS as ARGUMENTS hold them, as command-line words."""
    words = []
    for flag, keywords in RENDER_OPTIONS:
        value = getattr(arguments, keywords.get("dest", flag[2:].replace("-", "_")))
        for item in value if isinstance(value, list) else [] if value is None else [value]:
            words += [flag, str(item)]
    return words


def build_parser():
    parser = ArgumentParser(prog="python -m ssr_addon",
                            description="Stochastic screen-space reflections for Blender renders.")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=ArgumentParser)
    render = commands.add_parser("render", help="render frames with SSR, without it, or with Cycles")
    render.add_argument("scene", nargs="?",
                        help="a .blend file or a .py scene builder defining build(scene) "
                             "(default: the .blend file the Blender binary opened)")
    render.add_argument("--out", required=True, help="output folder")
    render.add_argument("--frames", help="frame N or range A-B (default: the current frame)")
    _add_render_options(render)
    render.add_argument("--warmup", type=int, metavar="K",
                        help="render the K frames before the first one to write, without writing them, so it "
                             "carries an uninterrupted run's history: what a farm chunk runs (default: 8 for a "
                             "range, and on resuming; none for a single frame, which renders as a still)")
    render.add_argument("--overwrite", action="store_true",
                        help="replace the run already in --out (its frames and report) instead of resuming it; "
                             "without it, a folder holding a different run is refused")
    farm = commands.add_parser("farm", help="render a frame range as chunks in several local processes, into one "
                                            "folder, as a render farm would")
    farm.add_argument("scene", help="a .blend file or a .py scene builder defining build(scene)")
    farm.add_argument("--out", required=True, help="output folder, shared by the chunks")
    farm.add_argument("--frames", required=True, help="range A-B to render")
    farm.add_argument("--chunk", type=int, default=30, help="frames per chunk (default 30)")
    farm.add_argument("--workers", type=int, default=1, help="chunks rendered at the same time (default 1)")
    farm.add_argument("--warmup", type=int, default=DEFAULT_WARMUP_FRAMES, metavar="K",
                      help=f"frames each chunk renders, unwritten, before its first (default {DEFAULT_WARMUP_FRAMES})")
    farm.add_argument("--overwrite", action="store_true", help="remove the run already in --out first")
    _add_render_options(farm)
    compare = commands.add_parser("compare", help="render one frame with SSR, cubemap, planar and no reflections, "
                                                  "side by side with the cost of each")
    compare.add_argument("scene", help="a .blend file or a .py scene builder defining build(scene)")
    compare.add_argument("--out", required=True, help="output folder for compare.png, compare.exr, compare.json")
    compare.add_argument("--resolution", help="WIDTHxHEIGHT (default: the scene's)")
    compare.add_argument("--frame", type=int, help="frame to render (default: the current frame)")
    compare.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                         help="override a chain setting (repeatable)")
    preview = commands.add_parser("preview", help="what the live viewport shows: the camera view captured from "
                                                  "EEVEE's viewport and refined until converged, with timings")
    preview.add_argument("scene", help="a .blend file or a .py scene builder defining build(scene)")
    preview.add_argument("--out", required=True, help="output folder for preview.exr, preview.png, first.png, "
                                                      "preview.json")
    preview.add_argument("--resolution", help="WIDTHxHEIGHT (default: the scene's)")
    preview.add_argument("--iterations", type=int, help="stop after this many iterations (default: when converged)")
    preview.add_argument("--orbit", type=int, default=0, metavar="N",
                         help="then orbit the camera's target N views, each shown as the live view shows a moving "
                              "view (orbit/view_KK.exr and .png)")
    preview.add_argument("--orbit-step", type=float, default=ORBIT_STEP_DEGREES, metavar="DEGREES",
                         help=f"degrees between two orbit views (default {ORBIT_STEP_DEGREES:g})")
    preview.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                         help="override a chain setting (repeatable)")
    return parser


def _command_line(argv):
    if argv is not None:
        return list(argv)
    if "--" in sys.argv:  # inside the Blender binary: our arguments follow "--"
        return sys.argv[sys.argv.index("--") + 1:]
    return sys.argv[1:]


def run(argv=None):
    """Parse and run; raises SSRError for anything the user can fix."""
    arguments = build_parser().parse_args(_command_line(argv))
    if arguments.command == "compare":
        return _compare(arguments)
    if arguments.command == "preview":
        return _preview(arguments)
    if arguments.command == "farm":
        return _farm(arguments)
    request = _render_request(arguments, frames=parse_frames(arguments.frames) if arguments.frames else None,
                              overwrite=arguments.overwrite)
    scene_path = arguments.scene or bpy.data.filepath
    if not scene_path:
        raise SSRError("no SCENE given and Blender has no .blend file open")
    scene = load_scene(arguments.scene) if arguments.scene else bpy.context.scene
    require_camera(scene)
    return run_render(scene, scene_path, request)


def _compare(arguments):
    request = RenderRequest(
        out_dir=arguments.out, resolution=parse_resolution(arguments.resolution) if arguments.resolution else None,
        settings=ChainSettings().with_overrides(arguments.overrides))
    scene = load_scene(arguments.scene)
    require_camera(scene)
    if arguments.frame is not None:
        scene.frame_set(arguments.frame)
    prepare_output_folder(arguments.out)
    sheet, labels, problems = compare_modes(scene, request)
    paths = [os.path.join(arguments.out, name) for name in ("compare.exr", "compare.png")]
    with written_together(paths) as (exr, png):
        write_rgba_exr(exr, sheet)
        write_display_png(png, sheet, scene)
    write_json(os.path.join(arguments.out, "compare.json"),
               {"scene": arguments.scene, "frame": scene.frame_current, "modes": labels, "problems": problems})
    for line in labels + problems:
        print(line)


def _render_request(arguments, **fields):
    """The RenderRequest the render options of ARGUMENTS (render's or farm's) ask for, with FIELDS."""
    return RenderRequest(
        out_dir=arguments.out, method=arguments.method, engine=arguments.engine,
        resolution=parse_resolution(arguments.resolution) if arguments.resolution else None,
        samples=arguments.samples, settings=ChainSettings().with_overrides(arguments.overrides),
        on_error=arguments.on_error, warmup=arguments.warmup, **fields)


def _farm(arguments):
    frames = parse_frames(arguments.frames)
    _render_request(arguments)  # checked here, once, rather than by every chunk; so are the scene and range
    scene = load_scene(arguments.scene)
    require_camera(scene)
    frame_numbers(scene, frames)
    return run_farm(os.path.abspath(arguments.scene), frames, arguments.chunk, arguments.workers,
                    os.path.abspath(arguments.out), arguments.warmup, _render_words(arguments), arguments.overwrite)


def _preview(arguments):
    if arguments.iterations is not None and arguments.iterations < 1:
        raise SSRError(f"--iterations must be at least 1, got {arguments.iterations}")
    if arguments.orbit < 0:
        raise SSRError(f"--orbit must be 0 or more views, got {arguments.orbit}")
    if not 0.0 < arguments.orbit_step <= 180.0:
        raise SSRError(f"--orbit-step must be more than 0 and at most 180 degrees, got {arguments.orbit_step:g}")
    settings = ChainSettings().with_overrides(arguments.overrides)
    resolution = parse_resolution(arguments.resolution) if arguments.resolution else None
    scene = load_scene(arguments.scene)
    return run_preview(scene, arguments.out, settings, resolution, arguments.iterations, arguments.orbit,
                       orbit_step=arguments.orbit_step)


class _Terminated(BaseException):
    """SIGTERM (what farm schedulers send), raised like KeyboardInterrupt so every cleanup runs."""


def _raise_terminated(signum, frame):
    raise _Terminated


def main(argv=None, command=run):
    """COMMAND(argv) with the errors a user can fix as one line (status 2), Ctrl-C (130) and SIGTERM
    (143) ending it cleanly; frames written so far stay complete."""
    previous_handler = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        command(argv)
    except SSRError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: frames written so far are complete", file=sys.stderr)
        sys.exit(130)
    except _Terminated:
        print("terminated (SIGTERM): frames written so far are complete", file=sys.stderr)
        sys.exit(128 + signal.SIGTERM)
    finally:
        signal.signal(signal.SIGTERM, previous_handler)
