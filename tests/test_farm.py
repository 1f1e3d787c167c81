"""A shot split over a farm: chunks rendered into one folder equal one machine's run, never lose each
other's frames, and the Flamenco job type compiles to the chunks and command lines they need."""
import json
import os
import shutil
import signal
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO, SCENES, read_exr, rgb, run_cli, scene_builder, terminate_once_written

JOB_TYPE = os.path.join(REPO, "ssr_addon", "batch", "stochastic_ssr_render.js")
HARNESS = os.path.join(os.path.dirname(__file__), "flamenco_harness.js")

# The hidden underside (a slab whose glowing underside only its mirror image shows) sliding
# sideways under a dollying camera for 24 frames: history, captures and their re-captures all
# carry from frame to frame. 64x36, 4 EEVEE samples, no lamp (one EEVEE render per frame).
SHOT = f"""
import sys
import bpy
sys.path.insert(0, {SCENES!r})
from hidden_underside import build as build_hidden


def build(scene):
    build_hidden(scene)
    bpy.data.objects.remove(bpy.data.objects["Sun"])
    scene.eevee.taa_render_samples = 4
    scene.render.resolution_x, scene.render.resolution_y = 64, 36
    scene.frame_start, scene.frame_end = 1, 24
    for name in ("SlabTop", "SlabUnderside"):
        slab = bpy.data.objects[name]
        slab.keyframe_insert("location", frame=1)
        slab.location.x += 1.5
        slab.keyframe_insert("location", frame=24)
    camera = scene.camera
    camera.keyframe_insert("location", frame=1)
    camera.location.x += 0.8
    camera.keyframe_insert("location", frame=24)
"""


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    return scene_builder(tmp_path_factory, "shot", SHOT)


def final(folder, frame):
    return rgb(read_exr(os.path.join(folder, f"frame_{frame:04d}.exr")))


def report(folder):
    with open(os.path.join(folder, "report.json"), encoding="utf-8") as stream:
        return json.load(stream)


@pytest.mark.blender
@pytest.mark.slow
def test_chunks_rendered_two_at_a_time_equal_one_run(shot, tmp_path):
    """Three 6-frame chunks of the shot's first 18 frames, two at a time into one folder, each warmed
    over the 8 frames before it (the last one's warm-up starts past the shot's first frame, so its
    history is truly cut short), against one uninterrupted run: every frame, each chunk's first
    included, within the bound a resumed run is held to (test_batch: mean absolute difference
    under 2e-3)."""
    one_run, chunks = tmp_path / "one_run", tmp_path / "chunks"
    run_cli("render", shot, "--frames", "1-18", "--out", one_run, timeout=1800)
    result = run_cli("farm", shot, "--frames", "1-18", "--chunk", "6", "--workers", "2", "--out", chunks,
                     timeout=1800)
    assert "3 chunks" in result.stdout and result.stdout.count(": done in") == 3, result.stdout
    differences = {frame: float(np.abs(final(chunks, frame) - final(one_run, frame)).mean())
                   for frame in range(1, 19)}
    assert max(differences.values()) < 2e-3, {frame: round(value, 5) for frame, value in differences.items()}
    assert [entry["frame"] for entry in report(chunks)["frames"]] == list(range(1, 19))
    assert sorted(run["frames"] for run in report(chunks)["runs"]) == ["1-6", "13-18", "7-12"]
    # A farm's worker takes each "Saved:" line for an output: the warm-up frames print none.
    for first in (1, 7, 13):
        log = (chunks / ".ssr_records" / "logs" / f"frames_{first:04d}-{first + 5:04d}.log").read_text()
        saved = [line for line in log.splitlines() if line.startswith("Saved:")]
        assert saved == [f"Saved: '{chunks / f'frame_{frame:04d}.png'}'" for frame in range(first, first + 6)], saved


def test_the_merged_report_keeps_every_run_s_frames_and_entries():
    """A run's record made when it claims the folder (fingerprint only) erases nothing the others
    recorded; a frame one run failed and another rendered is no longer failed."""
    from ssr_addon.batch.run_report import merge_reports
    full = {"fingerprint": {"method": "ssr"}, "scene": "shot.blend", "gpu": "A",
            "frames": [{"frame": 1}, {"frame": 2}], "failed_frames": [{"frame": 3, "error": "x"}],
            "runs": [{"host": "a", "frames": "1-3"}], "warnings": ["w"]}
    claimed = {"fingerprint": {"method": "ssr"}, "frames": [], "runs": [{"host": "b", "frames": "3-4"}]}
    rendered = {**claimed, "gpu": "B", "frames": [{"frame": 3}, {"frame": 4}], "warnings": ["w", "v"]}
    merged = merge_reports([full, claimed])
    assert merged["scene"] == "shot.blend" and merged["gpu"] == "A"
    assert [entry["frame"] for entry in merged["failed_frames"]] == [3]
    merged = merge_reports([full, rendered])
    assert [entry["frame"] for entry in merged["frames"]] == [1, 2, 3, 4] and merged["failed_frames"] == []
    assert merged["gpu"] == "B" and merged["warnings"] == ["w", "v"] and len(merged["runs"]) == 2


def render_chunk(shot, frames, out):
    """A chunk's process, started (the cheap `none` method: what is tested is the folder's records)."""
    return subprocess.Popen([sys.executable, "-m", "ssr_addon", "render", str(shot), "--method", "none",
                             "--frames", frames, "--out", str(out)], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)


@pytest.mark.blender
@pytest.mark.slow
def test_four_chunks_at_once_keep_every_record_and_a_killed_one_resumes(shot, tmp_path):
    out = tmp_path / "out"
    processes = [render_chunk(shot, frames, out) for frames in ("1-6", "7-12", "13-18", "19-24")]
    for process in processes:
        _, stderr = process.communicate(timeout=900)
        assert process.returncode == 0, stderr[-2000:]
    assert [entry["frame"] for entry in report(out)["frames"]] == list(range(1, 25))
    whole = run_cli("render", shot, "--method", "none", "--frames", "1-24", "--out", out)
    assert "all 24 frames are already complete" in whole.stdout, whole.stdout

    # A chunk killed halfway (what a farm does to a task it cancels) and run again.
    for frame in range(7, 13):
        for suffix in (".exr", ".passes.exr", ".png"):
            os.remove(out / f"frame_{frame:04d}{suffix}")
    returncode, stderr = terminate_once_written(render_chunk(shot, "7-12", out), out / "frame_0009.png")
    assert returncode == 128 + signal.SIGTERM, stderr[-2000:]
    rerun = run_cli("render", shot, "--method", "none", "--frames", "7-12", "--out", out)
    assert "resuming at frame" in rerun.stdout, rerun.stdout
    assert [entry["frame"] for entry in report(out)["frames"]] == list(range(1, 25))
    whole = run_cli("render", shot, "--method", "none", "--frames", "1-24", "--out", out)
    assert "all 24 frames are already complete" in whole.stdout, whole.stdout
    assert not [name for name in os.listdir(out) if name.endswith(".partial")]


def node():
    """Node from the project's dev dependencies (package.json; `make test` installs them), else the PATH's."""
    local = os.path.join(REPO, "node_modules", ".bin", "node")
    found = local if os.path.exists(local) else shutil.which("node")
    assert found, "Node is needed to compile the Flamenco job type: run `npm install` (make test does)"
    return found


def compile_job(tmp_path, **settings):
    """The tasks the job type compiles SETTINGS to, or {"error": ...}."""
    given = {"output_folder": "/farm/shot_out", "addon_folder": "/opt/blender/extensions/stochastic_ssr",
             "blendfile": "/farm/shot.blend", **settings}
    path = tmp_path / "settings.json"
    path.write_text(json.dumps(given))
    result = subprocess.run([node(), HARNESS, JOB_TYPE, str(path)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout)


def render_words(task):
    """The add-on's command line in TASK: the words after Blender's "--"."""
    (command,) = task["commands"]
    assert command["type"] == "blender-render"
    parameters = command["parameters"]
    assert parameters["exe"] == "{blender}" and parameters["blendfile"] == "/farm/shot.blend"
    args = parameters["args"]
    assert args[0] == "--python-expr" and "/opt/blender/extensions/stochastic_ssr" in args[1]
    return args[args.index("--") + 1:]


@pytest.mark.parametrize("frames, chunk_size, expected", [
    ("1-240", 30, [(1 + 30 * k, 30 + 30 * k) for k in range(8)]),
    ("1-100", 30, [(1, 30), (31, 60), (61, 90), (91, 100)]),   # does not divide evenly
    ("1-32", 30, [(1, 30), (31, 32)]),                          # two frames left: frameChunker's "31,32"
    ("47", 30, [(47, 47)]),                                     # one frame
    ("10..19", 500, [(10, 19)]),                                # a chunk larger than the range
])
def test_the_job_type_compiles_one_task_per_chunk(tmp_path, frames, chunk_size, expected):
    from ssr_addon.batch.cli import build_parser
    from ssr_addon.batch.farm import chunk_ranges
    compiled = compile_job(tmp_path, frames=frames, chunk_size=chunk_size, warmup=5,
                           render_options="--resolution 1920x1080 --set 'thickness=0.1'")
    assert compiled["label"] == "Stochastic SSR Render"
    ranges = []
    for task in compiled["tasks"]:
        arguments = build_parser().parse_args(render_words(task))  # words the add-on's CLI takes
        assert arguments.command == "render" and arguments.scene is None  # the .blend Blender opened
        assert arguments.warmup == 5 and arguments.out == "/farm/shot_out"
        assert arguments.overrides == ["preset=balanced", "thickness=0.1"] and arguments.resolution == "1920x1080"
        first, _, last = arguments.frames.partition("-")
        ranges.append((int(first), int(last)))
    assert ranges == expected
    assert chunk_ranges(expected[0][0], expected[-1][1], chunk_size) == expected  # `farm` cuts the same chunks


@pytest.mark.parametrize("settings, named", [
    (dict(frames="1-10,20-25"), "one range"),
    (dict(frames="20-10"), "reversed"),
    (dict(frames="1-10", chunk_size=0), "chunk_size"),
])
def test_the_job_type_refuses_what_it_cannot_chunk(tmp_path, settings, named):
    assert named in compile_job(tmp_path, **settings)["error"]
