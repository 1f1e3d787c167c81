"""An output folder holds one run: resumed only by the same run, refused to any other, and a
report that lists every frame in strict JSON. Signals leave only complete frames behind."""
import json
import os
import signal
import subprocess
import sys

import pytest

from conftest import REPO, SCENES, run_cli, terminate_once_written
from test_cli_errors import error_lines

pytestmark = [pytest.mark.blender, pytest.mark.slow]

SMALL = ("--resolution", "64x36")


def strict_json(path):
    def refuse(constant):
        raise ValueError(f"{path} is not strict JSON: {constant}")
    with open(path, encoding="utf-8") as stream:
        return json.load(stream, parse_constant=refuse)


def frames_in(folder):
    return sorted(name for name in os.listdir(folder) if not name.startswith(("report", ".ssr_records")))


@pytest.fixture(scope="module")
def used_folder(dolly, tmp_path_factory):
    """A folder holding frame 1 of the dolly scene without SSR."""
    folder = tmp_path_factory.mktemp("used")
    run_cli("render", dolly, "--method", "none", "--frames", "1", "--out", folder, *SMALL)
    return folder


@pytest.mark.parametrize("case, arguments, named", [
    ("another scene", [os.path.join(SCENES, "mirror_floor.py"), "--method", "none"], "scene"),
    ("another method", ["DOLLY", "--method", "ssr"], "method"),
    ("another setting", ["DOLLY", "--method", "none", "--set", "thickness=0.5"], "settings (thickness)"),
    ("other samples", ["DOLLY", "--method", "none", "--samples", "2"], "samples"),
])
def test_another_run_into_a_used_folder_is_refused(used_folder, dolly, case, arguments, named):
    before = {name: os.path.getmtime(used_folder / name) for name in os.listdir(used_folder)}
    scene = str(dolly) if arguments[0] == "DOLLY" else arguments[0]
    result = run_cli("render", scene, *arguments[1:], "--frames", "1", "--out", used_folder, *SMALL, check=False)
    lines = error_lines(result)
    assert result.returncode == 2, result.stdout + result.stderr
    assert len(lines) == 1 and named in lines[0] and "--overwrite" in lines[0], lines
    assert {name: os.path.getmtime(used_folder / name) for name in os.listdir(used_folder)} == before
    assert strict_json(used_folder / "report.json")["scene"] == str(dolly)


def test_overwrite_replaces_the_run(dolly, tmp_path):
    run_cli("render", dolly, "--method", "none", "--frames", "1-2", "--out", tmp_path, *SMALL)
    other = os.path.join(SCENES, "mirror_floor.py")
    run_cli("render", other, "--method", "none", "--out", tmp_path, *SMALL, "--overwrite")
    report = strict_json(tmp_path / "report.json")
    assert report["scene"] == other and [entry["frame"] for entry in report["frames"]] == [1]
    # Frame 2 belonged to the replaced run: no folder mixes two runs.
    assert frames_in(tmp_path) == ["frame_0001.exr", "frame_0001.passes.exr", "frame_0001.png"]


def test_frames_without_a_report_are_refused(tmp_path):
    (tmp_path / "frame_0001.exr").write_bytes(b"someone else's frame")
    result = run_cli("render", os.path.join(SCENES, "mirror_floor.py"), "--method", "none", "--out", tmp_path,
                     *SMALL, check=False)
    assert result.returncode == 2 and "no report.json" in error_lines(result)[0]
    assert (tmp_path / "frame_0001.exr").read_bytes() == b"someone else's frame"


def test_report_keeps_every_frame_across_resumes_with_the_samples_used(dolly, tmp_path):
    """DOLLY's scene asks for 4 EEVEE samples; no --samples is given, so 4 are used and reported."""
    run_cli("render", dolly, "--method", "none", "--frames", "1-2", "--out", tmp_path)
    run_cli("render", dolly, "--method", "none", "--frames", "3-4", "--out", tmp_path)
    report = strict_json(tmp_path / "report.json")
    assert [entry["frame"] for entry in report["frames"]] == [1, 2, 3, 4]
    assert report["samples"] == 4
    assert report["fingerprint"]["samples"] == 4 and report["fingerprint"]["resolution"] == [64, 36]
    assert len(report["fingerprint"]["scene"]["sha256"]) == 64


def test_the_scenes_own_samples_render(dolly, monkeypatch):
    from ssr_addon.blender import render_passes
    from ssr_addon.blender.render_setup import decide_render
    from ssr_addon.blender.scene_io import load_scene
    scene = load_scene(str(dolly))
    seen = []
    real_render_to_exr = render_passes.render_to_exr

    def recording(scene, path, changes):
        seen.append(scene.eevee.taa_render_samples)
        return real_render_to_exr(scene, path, changes)
    monkeypatch.setattr(render_passes, "render_to_exr", recording)
    scene.eevee.taa_render_samples = 3
    assert render_passes.render_passes(scene, decide_render(scene, "eevee")).samples == 3
    assert seen == [3]


def test_sigterm_leaves_complete_frames_and_no_temporary_files(dolly, tmp_path):
    out, temporary = tmp_path / "out", tmp_path / "tmp"
    temporary.mkdir()
    process = subprocess.Popen([sys.executable, "-m", "ssr_addon", "render", str(dolly), "--method", "none",
                                "--frames", "1-5", "--out", str(out)], cwd=REPO, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               env={**os.environ, "TMPDIR": str(temporary)})
    returncode, stderr = terminate_once_written(process, out / "frame_0001.exr")
    assert returncode == 128 + signal.SIGTERM, stderr[-2000:]
    assert "Traceback" not in stderr and "terminated" in stderr
    assert not [name for name in os.listdir(temporary) if name.startswith("ssr_passes_")]
    written = frames_in(out)
    frames = sorted({name[:len("frame_0001")] for name in written})
    assert written == [f"{frame}{suffix}" for frame in frames for suffix in (".exr", ".passes.exr", ".png")]
    reported = [entry["frame"] for entry in strict_json(out / "report.json")["frames"]]
    assert [f"frame_{frame:04d}" for frame in reported] == frames


def test_a_signal_as_a_frame_lands_ends_the_run_once_the_report_lists_it(dolly, tmp_path, monkeypatch):
    """SIGTERM the moment a frame's files are renamed into place, the narrowest window there is:
    the run still ends with status 143, and report.json lists exactly the frames on disk."""
    from ssr_addon.batch import cli, run
    write_frame = run.write_frame

    def written_then_terminated(*args, **kwargs):
        written = write_frame(*args, **kwargs)
        os.kill(os.getpid(), signal.SIGTERM)
        return written
    monkeypatch.setattr(run, "write_frame", written_then_terminated)
    with pytest.raises(SystemExit) as ended:
        cli.main(["render", str(dolly), "--method", "none", "--frames", "1-3", "--out", str(tmp_path), *SMALL])
    assert ended.value.code == 128 + signal.SIGTERM
    assert frames_in(tmp_path) == ["frame_0001.exr", "frame_0001.passes.exr", "frame_0001.png"]
    assert [entry["frame"] for entry in strict_json(tmp_path / "report.json")["frames"]] == [1]


def test_report_is_strict_json_even_with_non_finite_numbers(tmp_path):
    from ssr_addon.batch.outputs import write_json
    write_json(tmp_path / "report.json", {"mean": float("nan"), "frames": [{"ms": float("inf")}]})
    assert strict_json(tmp_path / "report.json") == {"mean": None, "frames": [{"ms": None}]}


def test_an_unreadable_material_is_one_warning_per_run(dolly, tmp_path):
    """Two frames, two objects with the same Toon material: one line in the log and in the report."""
    import bpy
    from ssr_addon.batch.request import RenderRequest
    from ssr_addon.batch.run import run_render
    from ssr_addon.blender.scene_io import load_scene
    scene = load_scene(str(dolly))
    toon = bpy.data.materials.new("toon")
    shader = toon.node_tree.nodes.new("ShaderNodeBsdfToon")
    toon.node_tree.nodes.remove(toon.node_tree.nodes["Principled BSDF"])
    toon.node_tree.links.new(shader.outputs[0], toon.node_tree.nodes["Material Output"].inputs["Surface"])
    for x in (-0.5, 0.5):
        bpy.ops.mesh.primitive_cube_add(size=0.3, location=(x, 0.0, 0.3))
        bpy.context.active_object.data.materials.append(toon)
    lines = []
    report = run_render(scene, str(dolly), RenderRequest(out_dir=str(tmp_path), method="none", frames=(1, 2)),
                        log=lines.append)
    warnings = [line for line in lines if line.startswith("warning:")]
    assert len(warnings) == 1 and "'toon'" in warnings[0] and "Toon BSDF" in warnings[0], lines
    assert report["warnings"] == [warnings[0][len("warning: "):]]
