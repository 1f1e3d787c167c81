"""Per-stage milliseconds of the SSR chain at 1600x900, as multiples of a full-screen copy.

    python -m lab chain-stages [--frames N] [--preset NAME ...] [--page docs/measurements.md [--block NAME]]

Each preset runs N frames of a still shot (after the first, each settles in an iteration or two);
the table gives the median per stage. The copy pass is measured in the same run.

Timing a stage waits for the GPU after it, and on a discrete GPU that wait costs more than a
cheap pass. So the second table runs the same frames again with nothing timed in between and
waits once: the chain's milliseconds per frame against a copy pass timed the same way.
"""
from ssr_addon.batch.cli import ArgumentParser
from ssr_addon.core.gpu_backend import describe_gpu
from ssr_addon.core.gpu_passes import CHAIN_STAGES
from ssr_addon.core.settings import PRESETS, preset
from .bench.speed import (COPY_PASS_LARGE, bench_scene_passes, chain_stage_ms, copy_pass_ms, queued_copy_pass_ms,
                          queued_frame_ms)
from .docs import require_page, rewrite_block


def main(argv):
    parser = ArgumentParser(prog="python -m lab chain-stages", description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--preset", nargs="+", default=list(PRESETS))
    parser.add_argument("--page", help="rewrite a block of this markdown page with the tables")
    parser.add_argument("--block", default="chain", help="the block to rewrite (default: chain)")
    arguments = parser.parse_args(argv)
    require_page(arguments.page)
    _, passes = bench_scene_passes()
    rows, queued = [], {}
    for name in arguments.preset:
        settings = preset(name)
        medians, inputs, state = chain_stage_ms(passes, settings, arguments.frames)
        rows.append((name, medians))
        queued[name] = queued_frame_ms(inputs, settings, state, arguments.frames)
    copy_ms = copy_pass_ms(COPY_PASS_LARGE)
    queued_copy_ms = queued_copy_pass_ms(COPY_PASS_LARGE)
    lines = [f"$ make bench-chain    # on {describe_gpu()['renderer']}",
             f"inputs: {COPY_PASS_LARGE[0]}x{COPY_PASS_LARGE[1]}",
             f"full-screen copy pass: {copy_ms:.2f} ms", "",
             f"{'preset':<10}" + "".join(f"{stage:>15}" for stage in CHAIN_STAGES) + f"{'total':>15}"]
    for name, medians in rows:
        total = sum(medians.values())
        cells = "".join(f"{ms:8.2f} ({ms / copy_ms:4.1f}x)" for ms in medians.values())
        lines.append(f"{name:<10}{cells}{total:8.2f} ({total / copy_ms:5.1f}x)")
    lines += ["", f"queued, one wait per run: copy pass {queued_copy_ms:.3f} ms"]
    lines += [f"{name:<10}{frame_ms:8.2f} ms per frame ({frame_ms / queued_copy_ms:5.1f}x)"
              for name, frame_ms in queued.items()]
    text = "\n".join(lines)
    print(text)
    if arguments.page:
        rewrite_block(arguments.page, arguments.block, f"```\n{text}\n```", "Benchmarks")
