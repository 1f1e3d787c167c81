"""When the chain's stages are timed apart: a GPU wait after each costs a frame time, so a
render does without them and the bench pays for them only on the frames it times stage by stage."""
import types

import numpy as np

from lab.bench import contenders as bench_contenders
from ssr_addon.core import gpu_backend
from ssr_addon.core.gpu_backend import StageTimer
from ssr_addon.core.settings import ChainSettings


def test_a_render_timer_never_waits_for_the_gpu_and_a_benchmark_timer_waits_after_each_stage(monkeypatch):
    waited = []
    monkeypatch.setattr(gpu_backend, "wait_for", waited.append)
    render_timer, bench_timer = StageTimer(wait_for_gpu=False), StageTimer()
    for timer in (render_timer, bench_timer):
        for stage in ("trace", "resolve"):
            timer.lap(stage, stage + " output")
        timer.lap("readback")
        assert set(timer.milliseconds) == {"trace", "resolve", "readback"}
    assert waited == ["trace output", "resolve output"]


def test_bench_frames_alternate_between_stage_timing_and_whole_frames(monkeypatch):
    """Frame 1 is left out; then stage-by-stage frames give the stage table, the others the frame
    times, each stage its fastest over its own frames."""
    requests = []

    def fake_render_frame(scene, request, state, fallbacks=None):
        requests.append(request.time_stages)
        apart = request.time_stages
        timer = types.SimpleNamespace(milliseconds={"render": 100.0 + len(requests), "trace": 5.0 if apart else 1.0,
                                                    "readback": 1.0 if apart else 4.0})
        return types.SimpleNamespace(final=np.zeros((2, 2, 4))), timer

    monkeypatch.setattr(bench_contenders, "render_frame", fake_render_frame)
    scene = types.SimpleNamespace(frame_current=1)
    contender = bench_contenders.Contender("ssr balanced", "ssr", ChainSettings())
    options = types.SimpleNamespace(frames=6, out_dir="", resolution=(4, 4), eevee_samples=1)
    _, stages, whole = bench_contenders.run_contenders(scene, [contender], options)["ssr balanced"]
    assert requests == [False, True, False, True, False, True]
    assert stages == {"render": 102.0, "trace": 5.0, "readback": 1.0}
    assert whole == {"render": 103.0, "trace": 1.0, "readback": 4.0}
