"""Batch animation: frames in order with history, resumable, nothing half-written."""
import json
import os

import numpy as np
import pytest

from conftest import read_exr, rgb, run_cli

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def final(folder, frame):
    return rgb(read_exr(os.path.join(folder, f"frame_{frame:04d}.exr")))


@pytest.fixture(scope="module")
def uninterrupted(dolly, tmp_path_factory):
    folder = tmp_path_factory.mktemp("uninterrupted")
    result = run_cli("render", dolly, "--frames", "1-4", "--out", folder)
    return folder, result


def test_frames_report_their_iterations_and_costs(uninterrupted):
    folder, result = uninterrupted
    with open(folder / "report.json", encoding="utf-8") as stream:
        report = json.load(stream)
    assert [entry["frame"] for entry in report["frames"]] == [1, 2, 3, 4]
    # Every frame converges like a still: the first from accumulate_iterations (16 at balanced)
    # iterations, the others from their history (whatever the dolly uncovers starts afresh).
    iterations = [entry["iterations"] for entry in report["frames"]]
    assert iterations[0] >= 16 and all(1 <= count <= 256 for count in iterations), iterations
    assert report["mean_ms_per_frame"]["addon_over_render"] > 0
    assert "x the render" in result.stdout
    assert "4/4 frames" in result.stderr and "ETA" in result.stderr


def test_resume_keeps_complete_frames_and_matches_an_uninterrupted_run(uninterrupted, dolly, tmp_path):
    reference, _ = uninterrupted
    # An interrupted run: frames 1-2 complete, frame 3 half-written, frame 4 never started.
    run_cli("render", dolly, "--frames", "1-2", "--out", tmp_path)
    (tmp_path / ".frame_0003.exr.partial").write_bytes(b"half")
    kept = os.path.getmtime(tmp_path / "frame_0002.exr")

    result = run_cli("render", dolly, "--frames", "1-4", "--out", tmp_path)
    assert "resuming at frame 3" in result.stdout
    assert os.path.getmtime(tmp_path / "frame_0002.exr") == kept
    assert sorted(os.listdir(tmp_path)) == sorted(os.listdir(reference))
    for frame in (3, 4):
        # Same rays (Halton indices follow the frame number) and a re-warmed history:
        # the resumed frames match the uninterrupted run to EEVEE's own noise.
        difference = np.abs(final(tmp_path, frame) - final(reference, frame))
        assert difference.mean() < 2e-3, (frame, difference.mean())


def test_frame_range_outside_the_scene(dolly, tmp_path):
    result = run_cli("render", dolly, "--frames", "3-9", "--out", tmp_path, check=False)
    assert "frames 1-5" in result.stderr
    assert result.returncode == 2
    assert "outside scene" in result.stderr and "Traceback" not in result.stderr
    assert not os.listdir(tmp_path)


def test_a_failing_frame_is_reported_and_skipped(dolly, tmp_path, monkeypatch):
    """--on-error skip: the other frames are written, the failure is in the report and the exit status."""
    from ssr_addon.batch import run
    from ssr_addon.batch.request import RenderRequest
    from ssr_addon.blender.scene_io import load_scene
    from ssr_addon.core.errors import SSRError
    real_render_frame = run.render_frame

    def failing_on_frame_2(scene, request, state=None, **options):
        if scene.frame_current == 2:
            raise SSRError("frame 2: the result has NaN or Inf pixels; nothing written")
        return real_render_frame(scene, request, state, **options)
    monkeypatch.setattr(run, "render_frame", failing_on_frame_2)
    scene = load_scene(str(dolly))
    request = RenderRequest(out_dir=str(tmp_path), method="none", frames=(1, 3), on_error="skip")
    with pytest.raises(SSRError, match="1 frame\\(s\\) failed: 2"):
        run.run_render(scene, str(dolly), request, log=lambda line: None)
    assert not any(name.startswith("frame_0002") for name in os.listdir(tmp_path))
    assert all(os.path.exists(tmp_path / f"frame_000{frame}.exr") for frame in (1, 3))
    with open(tmp_path / "report.json", encoding="utf-8") as stream:
        report = json.load(stream)
    assert [entry["frame"] for entry in report["failed_frames"]] == [2]


def test_an_interrupted_write_leaves_no_partial_frame(dolly, tmp_path, monkeypatch):
    from ssr_addon.batch import frame
    from ssr_addon.batch.request import RenderRequest
    from ssr_addon.batch.run import run_render
    from ssr_addon.blender.scene_io import load_scene

    def interrupted(path, rgba, scene):
        raise KeyboardInterrupt
    monkeypatch.setattr(frame, "write_display_png", interrupted)
    scene = load_scene(str(dolly))
    request = RenderRequest(out_dir=str(tmp_path), method="none", frames=(1, 1))
    with pytest.raises(KeyboardInterrupt):
        run_render(scene, str(dolly), request, log=lambda line: None)
    assert not [name for name in os.listdir(tmp_path) if name.startswith(("frame_", ".frame_"))]


def test_compare_times_each_mode_after_a_warm_up_of_its_own(monkeypatch):
    """A mode's first render compiles EEVEE's shaders for its set-up: compare renders each mode
    once at a quarter of the size, then the one it times and shows."""
    import types
    import bpy
    from ssr_addon.batch import compare
    from ssr_addon.batch.request import RenderRequest
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(scene.camera)
    renders = []

    def fake_render_mode(scene, mode, request, state=None, **objects):
        renders.append((mode, request.resolution))
        width, height = request.resolution
        return types.SimpleNamespace(final=np.zeros((height, width, 4), np.float32)), None
    monkeypatch.setattr(compare, "render_mode", fake_render_mode)
    monkeypatch.setattr(compare, "comparison_sheet", lambda tiles: tiles)
    compare.compare_modes(scene, RenderRequest(out_dir="", resolution=(320, 180)))
    modes = [mode for mode, _, _ in compare.COMPARISON_MODES]
    assert renders == [step for mode in modes for step in ((mode, (80, 45)), (mode, (320, 180)))]
