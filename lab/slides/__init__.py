"""`python -m lab slides --out DIR`: the deck's comparisons, each rendered on a scene built
to show it and measured, as DIR/index.html (one section per slide), its PNGs and GIFs and
DIR/slides.json (every number the page shows).

The sections follow the deck (sections.SECTIONS): SSR on and off, the cubemap and planar
baselines, the basic algorithm's inputs, the linear raymarch, cheap against expensive rays,
importance sampling, reusing neighbours' rays, the temporal filter and its reprojection, sparse
tracing, filtered importance sampling, performance and the limits of screen space. They share
the bench's measuring parts: its Cycles references, metrics, charts and display transform.
`--sections ID ...` renders some of them only: into a folder that holds a run at the same size,
they replace their own sections there and the others stay.
"""
import json
import os
import time

from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.outputs import prepare_output_folder, write_json
from ssr_addon.batch.request import parse_resolution
from ssr_addon.core.errors import SSRError
from .context import SlideContext
from .page import write_page
from .sections import SECTIONS

QUICK_RESOLUTION = (128, 72)
DEFAULT_RESOLUTION = (480, 270)


def section_ids():
    """The id of every section, in the deck's order: what --sections accepts."""
    return [build.__name__ for build in SECTIONS]


def main(argv):
    parser = ArgumentParser(prog="python -m lab slides",
                            description="the deck's comparisons, each rendered and measured: index.html, its PNGs "
                                        "and slides.json")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--resolution", help="WIDTHxHEIGHT (default: 480x270; 128x72 with --quick)")
    parser.add_argument("--quick", action="store_true", help="small images and few samples, for a quick check")
    parser.add_argument("--sections", nargs="+", metavar="ID",
                        help="render only these sections (their ids are the page's anchors, e.g. temporal_filter)")
    arguments = parser.parse_args(argv)
    return run_slides(arguments.out, parse_resolution(arguments.resolution) if arguments.resolution else None,
                      arguments.quick, arguments.sections)


def run_slides(out_dir, resolution=None, quick=False, only=None, log=print):
    """Render and measure every section (or those ONLY names) into OUT_DIR; returns the
    slides.json content."""
    unknown = sorted(set(only or ()) - set(section_ids()))
    if unknown:
        raise SSRError(f"--sections: no section {', '.join(unknown)}; expected some of {', '.join(section_ids())}")
    resolution = resolution or (QUICK_RESOLUTION if quick else DEFAULT_RESOLUTION)
    prepare_output_folder(out_dir)
    context = SlideContext(out_dir, resolution, quick, log)
    sections = []
    for build in SECTIONS:
        if only and build.__name__ not in only:
            continue
        started = time.perf_counter()
        section = {"id": build.__name__, **build(context)}
        log(f"{section['title']} ({time.perf_counter() - started:.0f} s): "
            + ", ".join(f"{key} {value}" for key, value in section["numbers"].items()))
        sections.append(section)
    report = {"resolution": list(resolution), "quick": quick, "eevee_samples": context.samples,
              "reference_samples": context.reference_samples,
              "sections": _merged(sections, _earlier_sections(out_dir, resolution, quick, log)) if only else sections}
    write_json(os.path.join(out_dir, "slides.json"), report)
    write_page(os.path.join(out_dir, "index.html"), report)  # last: the page names only what exists
    return report


def _earlier_sections(out_dir, resolution, quick, log):
    """The sections of OUT_DIR's slides.json when it was made at RESOLUTION and QUICK alike (a
    page mixes no sizes); else none."""
    path = os.path.join(out_dir, "slides.json")
    if not os.path.exists(path):
        return []
    try:
        with open(path, encoding="utf-8") as stream:
            earlier = json.load(stream)
    except (OSError, ValueError) as error:
        log(f"{path} cannot be read ({error}): the page shows only the sections run now")
        return []
    if earlier.get("resolution") != list(resolution) or earlier.get("quick") != quick:
        log(f"{path} holds a run at {earlier.get('resolution')} (quick {earlier.get('quick')}): "
            "the page shows only the sections run now")
        return []
    return earlier.get("sections", [])


def _merged(sections, earlier):
    """SECTIONS run now, with EARLIER's others, in the deck's order."""
    by_id = {section["id"]: section for section in earlier}
    by_id.update((section["id"], section) for section in sections)
    return [by_id[key] for key in section_ids() if key in by_id]
