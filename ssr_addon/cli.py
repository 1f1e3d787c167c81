"""Command line: `python -m ssr_addon render SCENE --out DIR ...`.

Also reachable from the Blender binary:
    blender -b --python-expr "import ssr_addon.cli; ssr_addon.cli.main()" -- render SCENE --out DIR
Errors the user can fix print one line and exit with status 2.
"""
import argparse
import sys

from .errors import SSRError
from .params import ChainSettings
from .render_job import METHODS, RenderRequest, parse_frames, parse_resolution, run_render
from .scene_io import load_scene, require_camera


class _ArgumentParser(argparse.ArgumentParser):
    def error(self, message):
        raise SSRError(message)


def build_parser():
    parser = _ArgumentParser(prog="python -m ssr_addon",
                             description="Stochastic screen-space reflections for Blender renders.")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_ArgumentParser)
    render = commands.add_parser("render", help="render frames with SSR, without it, or with Cycles")
    render.add_argument("scene", help="a .blend file or a .py scene builder defining build(scene)")
    render.add_argument("--out", required=True, help="output folder")
    render.add_argument("--method", default="ssr", choices=METHODS)
    render.add_argument("--engine", default="eevee", choices=("eevee", "cycles"),
                        help="engine that renders the input passes")
    render.add_argument("--resolution", help="WIDTHxHEIGHT (default: the scene's)")
    render.add_argument("--frames", help="frame N or range A-B (default: the current frame)")
    render.add_argument("--samples", type=int, help="EEVEE or Cycles samples per pixel")
    render.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a chain setting, e.g. --set thickness=0.1 (repeatable)")
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
    request = RenderRequest(
        out_dir=arguments.out, method=arguments.method, engine=arguments.engine,
        resolution=parse_resolution(arguments.resolution) if arguments.resolution else None,
        frames=parse_frames(arguments.frames) if arguments.frames else None,
        samples=arguments.samples, settings=ChainSettings().with_overrides(arguments.overrides))
    scene = load_scene(arguments.scene)
    require_camera(scene)
    return run_render(scene, arguments.scene, request)


def main(argv=None):
    try:
        run(argv)
    except SSRError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: frames written so far are complete", file=sys.stderr)
        sys.exit(130)
