"""Cycles composite semantics, against Cycles truth, on the emissive-panel scene.

Cycles writes what a glossy bounce gets from an emitter (a lamp, the world, an emissive
surface: one bounce, so direct light) to Glossy Direct, and the light other surfaces
reflect to Glossy Indirect. SSR fetches on-screen pixels, the emissive panel's radiance
included, so the composite must take the panel's reflection out of Glossy Direct as well,
and must keep the lamp's, which no screen pixel shows. The panel and its reflection are
bright, so subtracting the wrong light is off by the whole reflection: +100% when the
panel's reflection stays in (Glossy Indirect alone subtracted, as before), the whole
highlight when the lamp's goes too (all of Glossy Direct subtracted).
"""
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import REPO, SCENES, RenderedScene

pytestmark = [pytest.mark.blender, pytest.mark.slow]

SCENE = os.path.join(SCENES, "emissive_panel.py")
WIDTH, HEIGHT = 160, 90
RESOLUTION = f"{WIDTH}x{HEIGHT}"
SAMPLES = "1024"           # Cycles under SSR: a small bright highlight needs many samples per pixel
REFERENCE_SAMPLES = "2048"  # the truth, an estimate of its own (under 1% from 4096 samples already at 256)
RAW_SAMPLES = 256
# Composites fed other light as "what SSR replaces" (the same CLI with render_passes.py patched):
# before the fix, Glossy Indirect alone; the opposite mistake, all of Glossy Direct too.
VARIANTS = {
    "glossy_indirect_only": "passes.emitter_specular = lambda scene, folder, lamps, timer: 0.0",
    "all_glossy": "passes.offscreen_lamps = lambda scene: []",
}
WITHIN = 0.10   # the goal: the reflection SSR stands in for is right to a tenth of it


def render_cycles_ssr(folder, patch=None):
    code = "import sys\nimport ssr_addon.blender.render_passes as passes\n" + (patch or "") + \
        "\nfrom ssr_addon.batch.cli import main\nmain(sys.argv[1:])"
    result = subprocess.run([sys.executable, "-c", code, "render", SCENE, "--engine", "cycles", "--method", "ssr",
                             "--out", str(folder), "--resolution", RESOLUTION, "--samples", SAMPLES],
                            cwd=REPO, capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    return RenderedScene(str(folder))


@pytest.fixture(scope="module")
def runs(render_scene, tmp_path_factory):
    """The Cycles truth, SSR on Cycles as it is, and the two mistaken composites."""
    truth = render_scene("emissive_panel", "cycles", "--resolution", RESOLUTION, "--samples", REFERENCE_SAMPLES)
    ssr = render_scene("emissive_panel", "ssr", "--engine", "cycles", "--resolution", RESOLUTION,
                       "--samples", SAMPLES)
    variants = {name: render_cycles_ssr(tmp_path_factory.mktemp(name), patch) for name, patch in VARIANTS.items()}
    return {"truth": truth.final(), "ssr": ssr.final(), "passes": ssr.passes(),
            **{name: run.final() for name, run in variants.items()}}


def _render_raw(scene, hide_lamps, folder):
    """Cycles' own Glossy passes of SCENE, with or without its lamps, through plain bpy."""
    from ssr_addon.blender.overrides import TemporaryChanges
    from ssr_addon.blender.exr_render import render_to_exr
    with TemporaryChanges() as changes:
        changes.set_all(scene.render, engine="CYCLES", resolution_x=WIDTH, resolution_y=HEIGHT,
                        resolution_percentage=100)
        changes.set_all(scene.cycles, device="CPU", samples=RAW_SAMPLES, use_denoising=False)
        layer = scene.view_layers[0]
        for flag in ("use_pass_combined", "use_pass_normal", "use_pass_glossy_direct",
                     "use_pass_glossy_indirect", "use_pass_glossy_color"):
            changes.set(layer, flag, True)
        for obj in scene.objects:
            if obj.type == "LIGHT" and hide_lamps:
                changes.set(obj, "hide_render", True)
        return render_to_exr(scene, os.path.join(folder, f"raw_{hide_lamps}.exr"), changes)


@pytest.fixture(scope="module")
def cycles_raw(tmp_path_factory):
    """Raw Cycles passes with and without the lamp, and the regions, from the scene's geometry."""
    import runpy
    from ssr_addon.blender.scene_io import camera_matrices, load_scene
    scene = load_scene(SCENE)
    constants = runpy.run_path(SCENE)
    view, projection = camera_matrices(scene, WIDTH, HEIGHT)
    folder = str(tmp_path_factory.mktemp("cycles_raw"))
    lit, unlit = (_render_raw(scene, hide, folder) for hide in (False, True))

    def pixel_box(points, margin):
        """Pixels inside the screen box of POINTS (world space), shrunk by MARGIN pixels."""
        clip = (projection @ view @ np.c_[points, np.ones(len(points))].T).T
        ndc = clip[:, :2] / clip[:, 3:]
        x, y = (ndc[:, 0] * 0.5 + 0.5) * WIDTH, (0.5 - ndc[:, 1] * 0.5) * HEIGHT
        rows, cols = np.mgrid[0:HEIGHT, 0:WIDTH] + 0.5
        return ((cols > x.min() + margin) & (cols < x.max() - margin)
                & (rows > y.min() + margin) & (rows < y.max() - margin)), x.min()

    # Mirror images in the floor (z -> -z): the panel, and the cube's face toward the camera.
    cx, cy, cz = constants["PANEL_CENTER"]
    half_width, half_height = constants["PANEL_SIZE"]
    panel, panel_left = pixel_box([(cx + sx * half_width, cy, -(cz + sz * half_height))
                                   for sx in (-1, 1) for sz in (-1, 1)], 2)
    cube = scene.objects["Cube"]
    (x0, y0, z0), (x1, _, z1) = cube.location - cube.scale, cube.location + cube.scale
    cube_face, _ = pixel_box([(x, y0, -z) for x in (x0, x1) for z in (z0, z1)], 2)
    color = lit["Glossy Color"][..., :3]
    lamp = color * np.maximum(lit["Glossy Direct"][..., :3] - unlit["Glossy Direct"][..., :3], 0.0)
    highlight = lamp.mean(-1) > 1.0
    floor = (lit["Normal"][..., 2] > 0.9) & (color.mean(-1) > 0.5)
    regions = {
        "panel": panel & floor,
        "cube": cube_face & floor & (lamp.max(-1) < 0.05),
        "sky": floor & (np.mgrid[0:HEIGHT, 0:WIDTH][1] + 0.5 < panel_left - 8),  # nothing there but the world
        "highlight": highlight & floor,
    }
    for name, mask in regions.items():
        assert mask.sum() >= 30, f"region {name} has only {mask.sum()} pixels"
    world = np.array(scene.world.node_tree.nodes["Background"].inputs["Color"].default_value[:3]) \
        * scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value
    return {"lit": lit, "unlit": unlit, "regions": regions, "world": world}


def share(part, whole, mask):
    """PART's share of WHOLE over MASK, per channel (region means)."""
    return part[mask].mean(0) / whole[mask].mean(0)


def test_cycles_puts_reflected_emitters_in_glossy_direct(cycles_raw):
    """What each Cycles pass holds, on the metal floor (all its light is glossy)."""
    lit, unlit, regions = cycles_raw["lit"], cycles_raw["unlit"], cycles_raw["regions"]
    combined, color = lit["Combined"][..., :3], lit["Glossy Color"][..., :3]
    direct, indirect = color * lit["Glossy Direct"][..., :3], color * lit["Glossy Indirect"][..., :3]
    for name in ("panel", "cube", "highlight"):
        print(f"Cycles {name}: Glossy Direct share {share(direct, combined, regions[name]).round(3)}, "
              f"Glossy Indirect share {share(indirect, combined, regions[name]).round(3)}, "
              f"without the lamp {share(color * unlit['Glossy Direct'][..., :3], direct, regions[name]).round(3)}")
    # The reflected panel is direct light (one bounce to an emitter); the panel (black, no
    # specular) reflects nothing, so there is next to no indirect light.
    assert np.all(share(direct, combined, regions["panel"]) > 0.95)
    assert np.all(share(indirect, combined, regions["panel"]) < 0.02)
    # The same without the lamp: the panel's reflection is not the lamp's.
    assert np.allclose(share(color * unlit["Glossy Direct"][..., :3], direct, regions["panel"]), 1.0, atol=0.02)
    # The reflected world is direct light too, and is the world's radiance (a uniform world).
    for layers in (lit, unlit):
        assert np.allclose(layers["Glossy Direct"][..., :3][regions["sky"]].mean(0), cycles_raw["world"], rtol=0.02)
    # The cube (diffuse, lit by the world, the panel and the lamp) is indirect light.
    assert np.all(share(indirect, combined, regions["cube"]) > 0.9)
    # The lamp's highlight (on the cube's reflection) is mostly direct light, all of it the lamp's.
    assert np.all(share(direct, combined, regions["highlight"]) > 0.8)
    assert np.all(share(color * unlit["Glossy Direct"][..., :3], direct, regions["highlight"]) < 0.05)


def test_split_passes_hold_the_lamp_apart(runs, cycles_raw):
    """The SSR run's passes: Specular Direct is the lamp alone, Specular Indirect the rest."""
    from conftest import rgb
    passes, regions = runs["passes"], cycles_raw["regions"]
    color = rgb(passes, "Specular Color")
    kept, replaced = color * rgb(passes, "Specular Direct"), color * rgb(passes, "Specular Indirect")
    combined = rgb(passes, "Combined")
    print("replaced share, panel:", share(replaced, combined, regions["panel"]).round(3),
          "kept share, panel:", share(kept, combined, regions["panel"]).round(3),
          "kept share, highlight:", share(kept, combined, regions["highlight"]).round(3))
    assert np.all(share(replaced, combined, regions["panel"]) > 0.95)
    assert np.all(share(kept, combined, regions["panel"]) < 0.02)
    assert np.all(share(kept, combined, regions["highlight"]) > 0.8)
    assert np.allclose(rgb(passes, "Specular Indirect")[regions["sky"]].mean(0), cycles_raw["world"], rtol=0.02)


def test_panel_reflection_counts_once(runs, cycles_raw):
    """Where the floor mirrors the emissive panel, SSR's reflection replaces Cycles' own."""
    panel = cycles_raw["regions"]["panel"]
    assert runs["passes"]["SSR Confidence.V"][panel].mean() > 0.9  # SSR does stand in there
    truth = runs["truth"][panel].mean(0)
    ratio = runs["ssr"][panel].mean(0) / truth
    before = runs["glossy_indirect_only"][panel].mean(0) / truth
    print(f"panel reflection / Cycles: ssr {ratio.round(3)}, Glossy Indirect only {before.round(3)}")
    assert np.all(np.abs(ratio - 1.0) < WITHIN), ratio
    # Subtracting Glossy Indirect alone keeps Cycles' reflection of the panel under SSR's.
    assert np.all(before > 1.5), before


def test_lamp_highlight_stays(runs, cycles_raw):
    """The lamp's highlight, where SSR replaced the reflection around it, is Cycles' own."""
    highlight = cycles_raw["regions"]["highlight"] & (runs["passes"]["SSR Confidence.V"] > 0.5)
    assert highlight.sum() >= 5
    truth = runs["truth"][highlight].mean(0)
    ratio = runs["ssr"][highlight].mean(0) / truth
    without_lamp = runs["all_glossy"][highlight].mean(0) / truth
    print(f"lamp highlight / Cycles: ssr {ratio.round(3)}, all Glossy Direct subtracted {without_lamp.round(3)}")
    assert np.all(np.abs(ratio - 1.0) < WITHIN), ratio
    assert np.all(without_lamp < 0.7), without_lamp


def test_world_and_surface_reflections_match_cycles(runs, cycles_raw):
    """Elsewhere on the floor: the sky (SSR misses, Cycles' reflection stays) and the cube."""
    regions = cycles_raw["regions"]
    for name in ("sky", "cube"):
        ratio = runs["ssr"][regions[name]].mean(0) / runs["truth"][regions[name]].mean(0)
        print(f"{name} reflection / Cycles: ssr {ratio.round(3)}")
        assert np.all(np.abs(ratio - 1.0) < WITHIN), (name, ratio)


def test_whole_image_is_closer_to_cycles_than_either_mistake(runs):
    from lab.bench import flip_error
    everywhere = np.ones(runs["truth"].shape[:2], bool)
    errors = {name: flip_error(runs["truth"], runs[name], everywhere)
              for name in ("ssr", "glossy_indirect_only", "all_glossy")}
    print("FLIP against Cycles:", {name: round(value, 4) for name, value in errors.items()})
    assert errors["ssr"] < min(errors["glossy_indirect_only"], errors["all_glossy"])
