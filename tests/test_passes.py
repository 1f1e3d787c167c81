"""Pass rendering: the roughness AOV follows whatever drives Roughness, and the scene is left untouched."""
import os

import bpy
import numpy as np
import pytest

from conftest import SCENES, metal_floor_under
from gpu_harness import passes_lamp_split
from ssr_addon.blender.lamp_renders import lamp_world_for_run
from ssr_addon.blender.render_passes import render_passes
from ssr_addon.blender.render_setup import decide_render
from ssr_addon.blender.scene_io import load_scene

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def _plane_with_roughness(name, x, wire_roughness):
    bpy.ops.mesh.primitive_plane_add(size=0.9, location=(x, 0, 0))
    plane = bpy.context.active_object
    plane.name = name
    material = bpy.data.materials.new(name)
    bsdf = material.node_tree.nodes["Principled BSDF"]
    wire_roughness(material.node_tree, bsdf.inputs["Roughness"])
    plane.data.materials.append(material)
    return plane


def _constant(tree, socket):
    socket.default_value = 0.3


def _math_chain(tree, socket):
    add = tree.nodes.new("ShaderNodeMath")
    add.operation = "ADD"
    add.inputs[0].default_value = 0.2
    add.inputs[1].default_value = 0.25
    tree.links.new(add.outputs[0], socket)


def _texture(tree, socket):
    image = bpy.data.images.new("grey", 4, 4)
    image.generated_color = (0.7, 0.7, 0.7, 1.0)
    image.colorspace_settings.name = "Non-Color"
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    tree.links.new(texture.outputs["Color"], socket)


def _rna_values(struct, depth=2):
    """Every readable property of an RNA struct as plain data, nested structs to DEPTH (IDs by name)."""
    values = {}
    for prop in struct.bl_rna.properties:
        if prop.identifier in ("rna_type", "linear_colorspace_settings") or prop.type == "COLLECTION":
            continue  # an unset linear colour space (factory files) is initialised by any EXR format setting
        try:
            value = getattr(struct, prop.identifier)
        except (AttributeError, RuntimeError):
            continue
        if prop.type == "POINTER":
            if isinstance(value, bpy.types.ID) or value is None:
                values[prop.identifier] = getattr(value, "name_full", None)
            elif depth > 0:
                values[prop.identifier] = _rna_values(value, depth - 1)
        elif hasattr(value, "__len__") and not isinstance(value, str):
            values[prop.identifier] = tuple(value)
        else:
            values[prop.identifier] = value
    return values


def _snapshot(scene):
    """Everything the pass render touches (every render, engine and view-layer setting), as plain data."""
    materials = {}
    for material in bpy.data.materials:
        tree = material.node_tree
        materials[material.name] = (
            sorted((n.name, n.bl_idname) for n in tree.nodes),
            sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in tree.links))
    layers = {layer.name: (_rna_values(layer, 1), [(a.name, a.type) for a in layer.aovs])
              for layer in scene.view_layers}
    objects = {obj.name: _rna_values(obj, 0) for obj in scene.objects}
    return (materials, layers, objects, _rna_values(scene.render), _rna_values(scene.eevee),
            _rna_values(scene.cycles), scene.world, sorted(bpy.data.worlds.keys()), sorted(bpy.data.images.keys()))


@pytest.fixture(scope="module")
def roughness_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    for name, x, wiring in (("constant", -1, _constant), ("chain", 0, _math_chain), ("texture", 1, _texture)):
        _plane_with_roughness(name, x, wiring)
    bpy.ops.mesh.primitive_plane_add(size=0.9, location=(0, 1, 0))  # no material at all
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = 3.0
    camera.location = (0, 0.5, 5)
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.render.resolution_x, scene.render.resolution_y = 60, 60
    return scene


def test_roughness_aov_follows_every_kind_of_input(roughness_scene):
    passes = render_passes(roughness_scene, decide_render(roughness_scene, "eevee", samples=1))
    roughness = passes.roughness
    # The camera sees x in [-1.5, 1.5] and y in [-1, 2]: 20 px per unit, row 0 at y = 2.
    def at(x, y):
        return roughness[int((2 - y) * 20), int((x + 1.5) * 20)]
    assert at(-1, 0) == pytest.approx(0.3, abs=2e-3)
    assert at(0, 0) == pytest.approx(0.45, abs=2e-3)
    assert at(1, 0) == pytest.approx(0.7, abs=4e-3)
    assert at(0, 1) == 1.0, "an object without a material is left to the probes"
    # F0 of the default dielectric Principled BSDF: ((1.5 - 1) / (1.5 + 1))^2 * 2 * 0.5 = 0.04.
    assert passes.f0[int(2 * 20), int(0.5 * 20)] == pytest.approx([0.04] * 3, abs=1e-3)
    assert at(-1.4, 1.9) == 1.0, "the sky traces nothing"


def test_scene_is_exactly_as_before(roughness_scene):
    before = _snapshot(roughness_scene)
    render_passes(roughness_scene, decide_render(roughness_scene, "eevee", samples=1, resolution=(32, 32)))
    assert _snapshot(roughness_scene) == before


def test_every_setting_is_restored_after_an_exception_halfway(roughness_scene, monkeypatch):
    """A failure after the render (every setting changed, AOVs wired) still leaves the scene as it was,
    the output format included (a PNG at 8 bits stayed at 16 bits through the EXR's 32)."""
    from ssr_addon.blender import exr_render
    roughness_scene.render.image_settings.file_format = "PNG"
    roughness_scene.render.image_settings.color_depth = "8"
    before = _snapshot(roughness_scene)

    def failing_read(path):
        raise RuntimeError("a bug halfway through the frame")
    monkeypatch.setattr(exr_render, "read_multilayer_exr", failing_read)
    with pytest.raises(RuntimeError, match="halfway"):
        render_passes(roughness_scene, decide_render(roughness_scene, "eevee", samples=1, resolution=(32, 32)))
    assert _snapshot(roughness_scene) == before


def test_passes_have_the_shapes_and_camera_of_the_render(roughness_scene):
    passes = render_passes(roughness_scene, decide_render(roughness_scene, "eevee", samples=1, resolution=(40, 20)))
    assert passes.size == (40, 20)
    assert passes.combined.shape == (20, 40, 4) and passes.normal.shape == (20, 40, 3)
    assert np.isfinite(passes.combined).all()
    # The 2:1 view spans y in [-0.25, 1.25]; row 16 is y = 0 on the "chain" plane,
    # whose normal faces the camera 5 units above it (orthographic: depth 5).
    assert np.allclose(passes.normal[16, 20], (0, 0, 1), atol=1e-2)
    assert passes.depth[16, 20] == pytest.approx(5.0, abs=1e-2)


def test_f0_is_the_surfaces_own_at_antialiased_edges(roughness_scene):
    """The pixel filter averages an AOV with the sky around an edge; F0, like roughness, is
    divided by the coverage, so edge pixels read the surface's 0.04, not a darker blend."""
    passes = render_passes(roughness_scene, decide_render(roughness_scene, "eevee", samples=16))
    covered = passes.f0.mean(-1) > 1e-4
    padded = np.pad(covered, 1, constant_values=False)
    beside_sky = ~(padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])
    edges = covered & beside_sky
    assert edges.sum() > 20, "the planes' silhouettes are antialiased"
    np.testing.assert_allclose(passes.f0[covered], 0.04, atol=4e-3)


def test_a_run_keeps_one_black_world_and_removes_it(roughness_scene):
    """The lamp-only render of every frame of a run (a rendered split: auto's is analytic and
    renders nothing) uses the same black world (a new one each frame made EEVEE rebuild its
    world lighting), with the same lamp light as a lone render's; the run leaves no world behind."""
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.location = (0, 0.5, 2)
    roughness_scene.collection.objects.link(lamp)
    worlds = set(bpy.data.worlds)
    setup = decide_render(roughness_scene, "eevee", samples=1, resolution=(32, 32), lamp_split="render")
    alone = render_passes(roughness_scene, setup)
    assert set(bpy.data.worlds) == worlds
    with lamp_world_for_run():
        first = render_passes(roughness_scene, setup)
        made = set(bpy.data.worlds) - worlds
        second = render_passes(roughness_scene, setup)
        assert len(made) == 1 and set(bpy.data.worlds) - worlds == made
    assert set(bpy.data.worlds) == worlds
    assert alone.specular_direct.max() > 0, "the lamp must light the planes"
    np.testing.assert_allclose(first.specular_direct, alone.specular_direct, atol=1e-5)
    np.testing.assert_allclose(second.specular_direct, alone.specular_direct, atol=1e-5)


def test_the_scenes_own_ray_tracing_is_kept_and_lamps_stay_alone(gpu_backend):
    """A scene with EEVEE's ray tracing on keeps it: its screen-space diffuse light brightens
    the corridor's walls (lit by the emissive stripes across it), where the add-on used to
    switch it off. The lamp-only render still holds lamps alone: ray tracing there would add
    the lamp-lit scene's reflections to the highlights SSR leaves in place."""
    scene = load_scene(os.path.join(SCENES, "glossy_corridor.py"))
    lamp = bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT"))
    lamp.location = (0, 4, 2.5)
    lamp.data.energy = 200
    scene.collection.objects.link(lamp)
    as_authored = render_passes(scene, decide_render(scene, "eevee", samples=4, resolution=(80, 45)))
    scene.eevee.use_raytracing = True
    traced = render_passes(scene, decide_render(scene, "eevee", samples=4, resolution=(80, 45)))
    assert scene.eevee.use_raytracing

    (authored_direct, authored_indirect), (traced_direct, traced_indirect) = map(passes_lamp_split,
                                                                                 (as_authored, traced))

    def diffuse_level(passes, direct, indirect):
        rough = np.abs(passes.roughness - 0.7) < 0.01  # the side walls (the stripes are 1.0)
        specular = passes.specular_color * (indirect + direct)
        return float((passes.combined[..., :3] - specular)[rough].mean())
    authored_level = diffuse_level(as_authored, authored_direct, authored_indirect)
    traced_level = diffuse_level(traced, traced_direct, traced_indirect)
    print(f"walls: {authored_level:.4f} as authored, {traced_level:.4f} ray traced")
    assert traced_level >= 1.1 * authored_level
    assert authored_direct.max() > 0, "the lamp must light the floor"
    np.testing.assert_allclose(traced_direct, authored_direct, atol=1e-4, rtol=0.02)


def _sun_behind_a_wall():
    """One low sun facing the camera over a glossy metal floor; a wall's shadow covers half
    of the sun's highlight on the floor (towards the sun: (0, 0.94, 0.34), the camera's
    mirror direction)."""
    scene = metal_floor_under("SUN")
    bpy.ops.mesh.primitive_cube_add(location=(-0.6, 3.5, 0.5), scale=(0.6, 0.1, 0.5))
    return scene, bpy.context.active_object


def test_the_unshadowed_lamp_split_matches_the_exact_split_for_one_lamp():
    """lamp_split=unshadowed renders the lamps without shadows (a fraction of a render's cost)
    and shadows them with the main render's Shadow pass: for one lamp that is the exact split's
    lamp light, within 2 % on the floor, though the wall's shadow takes much of it away."""
    scene, wall = _sun_behind_a_wall()
    exact = render_passes(scene, decide_render(scene, "eevee", samples=4, lamp_split="render"))
    unshadowed = render_passes(scene, decide_render(scene, "eevee", samples=4, lamp_split="unshadowed"))
    wall.hide_render = True
    unblocked = render_passes(scene, decide_render(scene, "eevee", samples=4, lamp_split="render"))
    floor = (np.abs(exact.roughness - 0.3) < 0.01) & (np.abs(unblocked.roughness - 0.3) < 0.01)
    lamp_light = exact.specular_direct[floor].sum()
    shadowed_share = 1 - lamp_light / unblocked.specular_direct[floor].sum()
    error = np.abs(unshadowed.specular_direct - exact.specular_direct)[floor].sum() / lamp_light
    print(f"the wall's shadow takes {shadowed_share:.1%} of the lamp light; unshadowed split error {error:.2%}")
    assert shadowed_share > 0.2, "the test needs a shadow across the highlight"
    assert error <= 0.02


def test_ssr_renders_over_eevees_light_probe_ray_tracing(gpu_backend, tmp_path):
    """The render SSR composites over lights diffuse surfaces as EEVEE's own ray tracing does
    (its horizon scan occludes light near geometry). Without ray tracing, the scene's default, the
    rolling ball's walls and boxes come out tens of percent brighter than Cycles' and EEVEE's."""
    from ssr_addon.batch.frame import render_frame
    from ssr_addon.batch.request import RenderRequest
    scene = load_scene(os.path.join(SCENES, "rolling_ball.py"))
    assert not scene.eevee.use_raytracing

    def image(method):
        images, _ = render_frame(scene, RenderRequest(out_dir=str(tmp_path), method=method, resolution=(64, 36),
                                                      samples=4))
        return images
    ssr = image("ssr")
    passes = ssr.passes
    diffuse = (passes.specular_color.mean(-1) < 0.1) & (passes.depth < 1e9)  # SSR leaves these alone
    assert diffuse.sum() > 100

    def brightness(images):
        return float(images.final[..., :3][diffuse].mean())
    eevee_rt, no_raytracing = brightness(image("eevee-rt")), brightness(image("none"))
    print(f"diffuse pixels: ssr {brightness(ssr):.4f}, eevee-rt {eevee_rt:.4f}, no ray tracing {no_raytracing:.4f}")
    assert no_raytracing > 1.2 * eevee_rt, "the scene must show the difference"
    # EEVEE's screen trace also gathers diffuse light from the screen, which the horizon scan
    # approximates: within 10 % (no ray tracing is 46 % off).
    assert brightness(ssr) == pytest.approx(eevee_rt, rel=0.1)
