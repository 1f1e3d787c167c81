"""Speed's yardstick: the full-screen copy pass, timed on this GPU in the same run."""
import statistics

from ..gpu_backend import StageTimer, empty_texture, ensure_backend
from ..shaders import get_pass

COPY_PASS_REPEATS = 20
COPY_PASS_LARGE = (1600, 900)


def copy_pass_ms(size, repeats=COPY_PASS_REPEATS):
    """Median milliseconds of the full-screen copy pass (one RGBA32F texelFetch per pixel) at SIZE."""
    copy, target = _copy_pass(size)
    samples = []
    for repeat in range(repeats + 1):
        timer = StageTimer()
        timer.lap("idle", target)  # start with the GPU idle
        copy()
        timer.lap("copy", target)
        if repeat:  # the first draw warms up (allocation, shader compilation)
            samples.append(timer.milliseconds["copy"])
    return statistics.median(samples)


def queued_copy_pass_ms(size, count=COPY_PASS_REPEATS):
    """Milliseconds per copy pass at SIZE when COUNT copies are queued and waited for once: the
    GPU's throughput, without the wait for each pass that copy_pass_ms includes (about half a
    millisecond on a discrete GPU, far more than the copy itself)."""
    copy, target = _copy_pass(size)
    copy()  # warm-up
    timer = StageTimer()
    timer.lap("idle", target)
    for _ in range(count):
        copy()
    timer.lap("copies", target)
    return timer.milliseconds["copies"] / count


def _copy_pass(size):
    """(a call that draws one full-screen copy at SIZE, the texture it draws into)."""
    ensure_backend()
    source, target = empty_texture(size), empty_texture(size)
    copy = get_pass("copy")
    return (lambda: copy.draw([target], samplers=(("source_tx", source),))), target


def _size_label(size):
    return f"{size[0]}x{size[1]}"
