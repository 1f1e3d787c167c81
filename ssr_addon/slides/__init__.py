"""`python -m ssr_addon slides --out DIR`: the deck's comparisons, each rendered on a scene built
to show it and measured, as DIR/index.html (one section per slide), its PNGs and DIR/slides.json
(every number the page shows).

The sections so far follow the deck's first part: SSR on and off, the cubemap and planar
baselines, the basic algorithm's inputs, the linear raymarch and cheap against expensive rays
(sections.SECTIONS). They share the bench's measuring parts: its Cycles references, metrics and
display transform.
"""
import os

from ..outputs import prepare_output_folder, write_json
from .context import SlideContext
from .page import write_page
from .sections import SECTIONS

QUICK_RESOLUTION = (128, 72)
DEFAULT_RESOLUTION = (480, 270)


def run_slides(out_dir, resolution=None, quick=False, log=print):
    """Render and measure every section into OUT_DIR; returns the slides.json content."""
    resolution = resolution or (QUICK_RESOLUTION if quick else DEFAULT_RESOLUTION)
    prepare_output_folder(out_dir)
    context = SlideContext(out_dir, resolution, quick, log)
    sections = []
    for build in SECTIONS:
        section = build(context)
        log(f"{section['title']}: " + ", ".join(f"{key} {value}" for key, value in section["numbers"].items()))
        sections.append(section)
    report = {"resolution": list(resolution), "quick": quick, "eevee_samples": context.samples,
              "reference_samples": context.reference_samples, "sections": sections}
    write_json(os.path.join(out_dir, "slides.json"), report)
    write_page(os.path.join(out_dir, "index.html"), report)  # last: the page names only what exists
    return report
