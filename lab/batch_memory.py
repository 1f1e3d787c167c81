"""Resident memory over a long 1600x900 batch run of the add-on's own per-frame work.

    python -m lab memory [--frames 240] [--no-write] [--page docs/measurements.md]

Every frame does what `render` does after the engine's render: upload the
passes, run the chain with temporal history, read the results back and write
the frame's three files. The engine render itself is left out (it is Blender's
memory, and minutes per frame in software GL): the passes of one render are
reused. Prints resident memory at frames 1, 60, 120 and 240 and the per-frame
milliseconds of each step.
"""
import os
import statistics
import tempfile

from ssr_addon.batch import frame as batch_frame
from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.batch.frame import FrameFallbacks, render_frame, write_frame
from ssr_addon.batch.request import RenderRequest
from ssr_addon.batch.run import return_large_buffers_to_the_system
from ssr_addon.core.chain import ChainState
from ssr_addon.core.settings import ChainSettings
from .bench.speed import COPY_PASS_LARGE as SIZE
from .bench.speed import bench_scene_passes
from .docs import require_page, rewrite_block


def resident_mib():
    with open("/proc/self/statm", encoding="ascii") as stream:
        return int(stream.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


def main(argv):
    parser = ArgumentParser(prog="python -m lab memory", description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=240)
    parser.add_argument("--no-write", action="store_true", help="skip writing the files")
    parser.add_argument("--page", help="rewrite the memory block of this markdown page with the resident memory")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    scene, passes = bench_scene_passes()
    # The engine render is replaced by the one set of passes rendered above.
    batch_frame.render_passes = lambda *args, **kwargs: passes
    return_large_buffers_to_the_system()  # as run_render does
    request = RenderRequest(out_dir="", settings=ChainSettings())
    state, fallbacks = ChainState(), FrameFallbacks()  # as a run holds them, frame to frame
    checkpoints = {1, 60, 120, 240, arguments.frames}
    stage_ms, resident = {}, []
    with tempfile.TemporaryDirectory() as folder:
        for frame in range(1, arguments.frames + 1):
            state.begin_frame(frame)
            images, timer = render_frame(scene, request, state, fallbacks)
            if not arguments.no_write:
                write_frame(folder, 1, images, scene)  # one frame's files, overwritten each time
                timer.lap("write")
            for stage, ms in timer.milliseconds.items():
                stage_ms.setdefault(stage, []).append(ms)
            if frame in checkpoints:
                resident.append(f"frame {frame:4d}: resident memory {resident_mib():8.1f} MiB")
                print(resident[-1], flush=True)
    print(f"\nper frame at {SIZE[0]}x{SIZE[1]} (median ms):")
    for stage, values in stage_ms.items():
        if stage != "render":
            print(f"  {stage:<14}{statistics.median(values):8.1f}")
    if arguments.page:
        rewrite_block(arguments.page, "memory", "```\n$ make bench-memory\n" + "\n".join(resident) + "\n```", "Benchmarks")
