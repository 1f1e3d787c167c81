"""Bad input: one clear line, a non-zero exit, nothing written."""
import os

import pytest

from conftest import SCENES, run_cli

pytestmark = [pytest.mark.blender, pytest.mark.slow]

NO_CAMERA = """
import bpy
def build(scene):
    bpy.ops.mesh.primitive_cube_add()
"""
NO_BUILD = "x = 1\n"
EXITS_IN_BUILD = """
import sys
def build(scene):
    sys.exit(0)
"""
EXITS_ON_LOAD = "import sys\nsys.exit(3)\n"
NON_SQUARE_PIXELS = f"""
import sys
sys.path.insert(0, {SCENES!r})
from mirror_floor import build as build_mirror_floor
def build(scene):
    build_mirror_floor(scene)
    scene.render.pixel_aspect_x = 1.1
"""


def error_lines(result):
    return [line for line in result.stderr.splitlines() if line.strip() and "EGL" not in line]


@pytest.mark.parametrize("case, extra, expected", [
    ("missing file", [], "scene file not found"),
    ("no camera", [], "has no active camera"),
    ("no build", [], "defines no build(scene)"),
    ("exits in build", [], "called sys.exit(0)"),
    ("exits on load", [], "called sys.exit(3)"),
    ("non-square pixels", [], "non-square pixels (pixel aspect 1.1:1)"),
    ("bad frames", ["--frames", "ten"], "--frames"),
    ("reversed frames", ["--frames", "9-3"], "reversed"),
    ("negative warm-up", ["--frames", "1-2", "--warmup", "-1"], "--warmup"),
    ("bad resolution", ["--resolution", "320by180"], "--resolution"),
    ("bad setting", ["--set", "thickness=thick"], "thickness"),
    ("unknown setting", ["--set", "colour=1"], "colour"),
    ("not a number", ["--set", "thickness=nan"], "finite"),
    ("infinite setting", ["--set", "max_distance=inf"], "finite"),
    ("split without a shadow pass", ["--engine", "cycles", "--set", "lamp_split=unshadowed"], "Shadow pass"),
    ("analytic split without a shadow pass", ["--engine", "cycles", "--set", "lamp_split=analytic"], "Shadow pass"),
])
def test_bad_input_gets_one_clear_line(tmp_path, case, extra, expected):
    scene = {"missing file": tmp_path / "absent.blend",
             "no camera": tmp_path / "no_camera.py",
             "no build": tmp_path / "no_build.py",
             "exits in build": tmp_path / "exits_in_build.py",
             "exits on load": tmp_path / "exits_on_load.py",
             "non-square pixels": tmp_path / "non_square.py"}.get(case, os.path.join(SCENES, "mirror_floor.py"))
    builders = {"no camera": NO_CAMERA, "no build": NO_BUILD, "exits in build": EXITS_IN_BUILD,
                "exits on load": EXITS_ON_LOAD, "non-square pixels": NON_SQUARE_PIXELS}
    if case in builders:
        scene.write_text(builders[case])
    out = tmp_path / "out"
    result = run_cli("render", scene, "--out", out, *extra, check=False)
    lines = error_lines(result)
    assert result.returncode == 2
    assert len(lines) == 1 and lines[0].startswith("error:") and expected in lines[0], result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists() or not os.listdir(out)


@pytest.mark.parametrize("extra, expected", [
    (["--frames", "1-3", "--chunk", "0"], "--chunk"),
    (["--frames", "1-3", "--workers", "0"], "--workers"),
    (["--frames", "1-100000"], "outside scene"),
    (["--frames", "1-3", "--warmup", "-2"], "--warmup"),
    ([], "--frames"),
])
def test_bad_farm_input_gets_one_clear_line(tmp_path, extra, expected):
    out = tmp_path / "out"
    result = run_cli("farm", os.path.join(SCENES, "mirror_floor.py"), "--out", out, *extra, check=False)
    lines = error_lines(result)
    assert result.returncode == 2
    assert len(lines) == 1 and lines[0].startswith("error:") and expected in lines[0], result.stderr
    assert not out.exists() or not os.listdir(out)


def test_unwritable_output_folder(tmp_path):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    result = run_cli("render", os.path.join(SCENES, "mirror_floor.py"), "--out", blocker / "out", check=False)
    lines = error_lines(result)
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith("error: cannot create output folder") and "Traceback" not in result.stderr


def test_corrupt_blend_file(tmp_path):
    corrupt = tmp_path / "corrupt.blend"
    corrupt.write_bytes(b"BLENDER-v500 this is not a blend file" * 10)
    result = run_cli("render", corrupt, "--out", tmp_path / "out", check=False)
    lines = error_lines(result)
    assert result.returncode == 2 and lines[-1].startswith("error: cannot open"), result.stderr
    assert "Traceback" not in result.stderr
