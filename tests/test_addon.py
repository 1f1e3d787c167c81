"""The add-on inside Blender (bpy module, headless): registration, settings,
panels, operators, baselines, the compositor and the extension package."""
import dataclasses
import json
import os
import subprocess
import sys
import textwrap
import zipfile
from dataclasses import replace
from types import SimpleNamespace

import bpy
import numpy as np
import OpenImageIO as oiio
import pytest

import ssr_addon
from conftest import REPO, SCENES
from synthetic import intersect_boxes, mirror_image
from ssr_addon.batch.compare import render_mode
from ssr_addon.batch.frame import render_frame
from ssr_addon.blender import result_image
from ssr_addon.blender.baselines import COMPARISON_MODES, apply_baseline
from ssr_addon.blender.comparison_sheet import SHEET_IMAGE
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.blender.scene_io import camera_matrices, load_scene
from ssr_addon.core import gpu_passes
from ssr_addon.core.layers import DEBUG_VIEW_LAYERS, exr_channels, frame_layers
from ssr_addon.core.settings import SETTINGS_SCHEMA, ChainSettings
from ssr_addon.ui import live, operators, overlay, panels
from ssr_addon.ui import properties as ui_properties

pytestmark = pytest.mark.blender

BLENDER_EXT = os.path.join(bpy.utils.system_resource("SCRIPTS"), "addons_core", "bl_pkg", "cli", "blender_ext.py")
sys.path.insert(0, SCENES)
from _common import add_camera, add_mesh, principled, set_render, set_world  # noqa: E402

SMALL = (64, 36)


@pytest.fixture
def addon():
    ssr_addon.register()
    yield
    ssr_addon.unregister()


def _empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def _mirror_floor(width, height):
    scene = load_scene(os.path.join(SCENES, "mirror_floor.py"))
    set_render(scene, width, height)
    return scene


# A mirror base carrying a red glowing block, both one object; a blue lantern stands beside it.
BASE_HALF = 2.0
BLOCK_LOW, BLOCK_HIGH = (-0.5, 0.3, 0.0), (0.5, 1.3, 1.0)
LANTERN_CENTRE, LANTERN_HALF = (2.6, 2.4, 1.0), 0.6


def _sculpture_scene():
    scene = _empty_scene()
    set_render(scene, *SMALL)
    set_world(scene, (0.02, 0.02, 0.02))
    (x0, y0, z0), (x1, y1, z1) = BLOCK_LOW, BLOCK_HIGH
    b = BASE_HALF
    vertices = [(-b, -b, 0), (b, -b, 0), (b, b, 0), (-b, b, 0),
                (x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    block_faces = ((4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7))
    faces = [(0, 1, 2, 3)] + [tuple(4 + index for index in face) for face in block_faces]
    mesh = bpy.data.meshes.new("Sculpture")
    mesh.from_pydata(vertices, [], faces)
    mesh.materials.append(principled("Mirror", base_color=(0.95, 0.95, 0.95), roughness=0.0, metallic=1.0))
    mesh.materials.append(principled("Glow", base_color=(0, 0, 0), roughness=1.0,
                                     emission=(1.0, 0.05, 0.05), emission_strength=5.0))
    for polygon in mesh.polygons:
        polygon.material_index = 0 if polygon.index == 0 else 1
    sculpture = bpy.data.objects.new("Sculpture", mesh)
    scene.collection.objects.link(sculpture)
    bpy.ops.mesh.primitive_cube_add(size=2 * LANTERN_HALF, location=LANTERN_CENTRE)
    bpy.context.active_object.data.materials.append(principled(
        "Blue", base_color=(0, 0, 0), roughness=1.0, emission=(0.05, 0.1, 1.0), emission_strength=5.0))
    add_camera(scene, (0.0, -5.0, 2.2), (0.0, 0.5, 0.0))
    return scene


def _pixel_rays(scene, width, height):
    """World-space origin and unit directions (H, W, 3) of the camera ray through each pixel centre."""
    view, projection = camera_matrices(scene, width, height)
    to_world = np.linalg.inv(projection.astype(np.float64) @ view)
    columns, rows = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    ndc = np.stack([columns / width * 2 - 1, 1 - rows / height * 2], axis=-1)
    def unproject(depth):
        points = np.concatenate([ndc, np.full(ndc.shape[:2] + (1,), depth), np.ones(ndc.shape[:2] + (1,))], -1)
        world = points @ to_world.T
        return world[..., :3] / world[..., 3:]
    near, far = unproject(-1.0), unproject(1.0)
    directions = far - near
    return near, directions / np.linalg.norm(directions, axis=-1, keepdims=True)


def _box_hit(origins, directions, low, high):
    """Distance along each ray to the box LOW..HIGH, inf where it misses."""
    return intersect_boxes(origins, directions, [(low, high)], np.full(origins.shape[:-1], np.inf))[0]


def _sphere_hit(origins, directions, centre, radius):
    offset = origins - np.asarray(centre)
    b = np.sum(offset * directions, axis=-1)
    discriminant = b * b - (np.sum(offset * offset, axis=-1) - radius * radius)
    t = -b - np.sqrt(np.maximum(discriminant, 0))
    return np.where((discriminant > 0) & (t > 0), t, np.inf)


def _mirror_mask(scene, width, height, floor_half, hit, occluders=()):
    """Pixels that see the z=0 mirror within |x|, |y| < FLOOR_HALF and whose mirror ray HIT()s the target."""
    origins, directions = _pixel_rays(scene, width, height)
    t_floor = -origins[..., 2] / directions[..., 2]
    points = origins + directions * t_floor[..., None]
    on_floor = (t_floor > 0) & (np.abs(points[..., 0]) < floor_half) & (np.abs(points[..., 1]) < floor_half)
    for occluder in occluders:  # geometry in front of the mirror
        on_floor &= occluder(origins, directions) > t_floor
    mirrored = mirror_image(directions, axis=2)
    return on_floor & np.isfinite(hit(points + mirrored * 1e-4, mirrored))


# --- registration and settings -------------------------------------------------------------------------------

def _addon_state():
    return {
        "types": set(dir(bpy.types)),
        "scene_ssr": hasattr(bpy.types.Scene, "ssr"),
        "property_group": ui_properties.SSRSceneSettings.is_registered,
        "ops": set(dir(bpy.ops.render)),
        "app_handlers": {name: len(getattr(bpy.app.handlers, name)) for name in dir(bpy.app.handlers)
                         if isinstance(getattr(bpy.app.handlers, name), list)},
        "overlay": overlay.is_registered(),
        "live": (live._draw_handle, live.running_session(), live._timer),
        "view3d_ops": set(dir(bpy.ops.view3d)),
    }


def test_register_unregister_twice_leaves_nothing_behind():
    before = _addon_state()
    assert not before["scene_ssr"] and not before["overlay"]
    for _ in range(2):
        ssr_addon.register()
        registered = _addon_state()
        assert registered["scene_ssr"] and registered["property_group"] and registered["overlay"]
        assert {"RENDER_PT_ssr", "RENDER_PT_ssr_tracing", "VIEW3D_PT_ssr"} <= registered["types"]
        assert {"ssr_render_frame", "ssr_render_animation", "ssr_compare", "ssr_setup_compositor"} <= registered["ops"]
        assert "ssr_live" in registered["view3d_ops"] and registered["live"][0] is not None
        handle = overlay._handle
        ssr_addon.unregister()
        assert _addon_state() == before
        with pytest.raises(ValueError):  # the draw callback is gone from the 3D view
            bpy.types.SpaceView3D.draw_handler_remove(handle, "WINDOW")


def test_property_group_has_every_schema_field_with_its_default(addon):
    properties = bpy.context.scene.ssr.bl_rna.properties
    kinds = {bool: "BOOLEAN", int: "INT", float: "FLOAT", str: "ENUM"}
    for spec in SETTINGS_SCHEMA:
        prop = properties[spec.name]
        kind = kinds[type(spec.default)] if spec.metadata["items"] or type(spec.default) is not str else "STRING"
        assert prop.type == kind, spec.name
        assert prop.description == spec.metadata["description"]
        if prop.type == "ENUM":
            assert prop.default == spec.default
            assert [item[0] for item in spec.metadata["items"]] == prop.enum_items.keys()
            continue
        if prop.type == "STRING":  # text the schema checks (the fallback levels)
            assert prop.default == spec.default
            continue
        assert prop.default == pytest.approx(spec.default, rel=1e-6), spec.name
        if spec.metadata["min"] is not None:
            assert (prop.hard_min, prop.hard_max) == pytest.approx((spec.metadata["min"], spec.metadata["max"]))
    assert ui_properties.chain_settings(bpy.context.scene.ssr) == _float32(ChainSettings())


def _float32(chain):
    """CHAIN with its floats rounded as a Blender FloatProperty stores them."""
    return dataclasses.replace(chain, **{spec.name: float(np.float32(getattr(chain, spec.name)))
                                         for spec in SETTINGS_SCHEMA if type(spec.default) is float})


def _other_value(spec):
    if type(spec.default) is bool:
        return not spec.default
    if type(spec.default) is str and not spec.metadata["items"]:
        return "off"  # the one free-text setting, fallback: any value other than its default "auto"
    if type(spec.default) is str:
        return next(item[0] for item in spec.metadata["items"] if item[0] != spec.default)
    low, high = spec.metadata["min"], spec.metadata["max"]
    value = low + (high - low) * 0.37
    return type(spec.default)(value if value != spec.default else low)


def test_presets_set_every_setting(addon):
    from ssr_addon.core.settings import preset
    from ssr_addon.ui.properties import chain_settings
    scene = bpy.context.scene
    for name in ("high", "draft"):
        assert bpy.ops.render.ssr_apply_preset(preset=name) == {"FINISHED"}
        assert chain_settings(scene.ssr) == _float32(preset(name))


def test_chain_settings_round_trip(addon):
    scene_settings = bpy.context.scene.ssr
    expected = ChainSettings(**{spec.name: _other_value(spec) for spec in SETTINGS_SCHEMA})
    assert expected != ChainSettings()
    for spec in SETTINGS_SCHEMA:
        setattr(scene_settings, spec.name, getattr(expected, spec.name))
    assert ui_properties.chain_settings(scene_settings) == _float32(expected)


def test_new_schema_fields_need_no_edit_to_settings_or_panels():
    @dataclasses.dataclass(frozen=True)
    class Extended:
        use_ssr: bool = True
        thickness: float = dataclasses.field(default=0.2, metadata={"description": "d", "min": 0.0, "max": 1.0})
        history: float = dataclasses.field(default=0.9, metadata={"group": "temporal", "description": "h"})
        edge_fade: float = dataclasses.field(default=0.1, metadata={"group": "fading", "description": "e"})
        rays: int = dataclasses.field(default=4, metadata={"group": "resolve", "description": "r"})
        mode: str = dataclasses.field(default="A", metadata={"group": "extra", "items": (("A", "A", ""), ("B", "B", ""))})
    schema = dataclasses.fields(Extended)
    assert ui_properties.grouped_fields(schema) == {
        "tracing": ["thickness"], "resolve": ["rays"], "temporal": ["history"], "fading": ["edge_fade"],
        "extra": ["mode"]}
    group = ui_properties.settings_group(schema)
    bpy.utils.register_class(group)
    try:
        properties = group.bl_rna.properties
        assert properties["history"].default == pytest.approx(0.9)
        assert properties["rays"].type == "INT" and properties["mode"].type == "ENUM"
        assert {"comparison_mode", "debug_view", "probe_object", "planar_object", "show_overlay"} <= set(properties.keys())
    finally:
        bpy.utils.unregister_class(group)


def test_debug_views_offered_are_the_ones_the_image_can_show():
    """The Debug View setting offers the final image and each layer a pass declares a view on,
    and every one of those layers is written to the passes EXR."""
    offered = [item[0] for item in ui_properties.UI_PROPERTIES["debug_view"].keywords["items"]]
    assert offered == ["FINAL", *DEBUG_VIEW_LAYERS]
    assert set(DEBUG_VIEW_LAYERS.values()) <= {layer.name for _, layer in frame_layers()}


# --- panels ----------------------------------------------------------------------------------------------------

class _Recorder:
    """Stands in for bpy.types.UILayout: records what a draw() asks for."""

    def __init__(self, log):
        self.log, self.active, self.enabled = log, True, True

    def _child(self, *args, **kwargs):
        return _Recorder(self.log)
    row = column = box = split = _child

    def prop(self, owner, name, **kwargs):
        self.log.append(("prop", name, self.active, kwargs.get("expand", False)))

    def label(self, text="", **kwargs):
        self.log.append(("label", text))

    def operator(self, idname, **kwargs):
        self.log.append(("operator", idname, self.enabled))
        return SimpleNamespace()  # the operator's properties, which draw code may set


def _draw(panel, method, scene):
    log = []
    fake = SimpleNamespace(layout=_Recorder(log), fields=getattr(panel, "fields", ()),
                           unavailable_reason=getattr(panel, "unavailable_reason", None))
    getattr(panel, method)(fake, SimpleNamespace(scene=scene))
    return log


def test_render_panels_draw_every_setting_and_grey_out_with_a_reason(addon):
    scene = _mirror_floor(*SMALL)
    sub_panels = [cls for cls in panels._registered if getattr(cls, "bl_parent_id", "") == "RENDER_PT_ssr"]
    assert [cls.bl_label for cls in sub_panels] == [group.title() for group in ui_properties.grouped_fields()]
    drawn = [entry[1] for panel in sub_panels for entry in _draw(panel, "draw", scene) if entry[0] == "prop"]
    assert sorted(drawn) == sorted(spec.name for spec in SETTINGS_SCHEMA if spec.name != "use_ssr")
    assert _draw(panels.RENDER_PT_ssr, "draw_header", scene) == [("prop", "use_ssr", True, False)]
    presets = [("label", "Preset")] + [("operator", "render.ssr_apply_preset", True)] * 3
    assert _draw(panels.RENDER_PT_ssr, "draw", scene) == presets

    scene.render.engine = "BLENDER_WORKBENCH"
    assert ("label", "Needs the EEVEE or Cycles render engine") in _draw(panels.RENDER_PT_ssr, "draw", scene)
    assert _draw(panels.RENDER_PT_ssr, "draw_header", scene)[0][2] is False
    assert not any(entry[2] for entry in _draw(sub_panels[0], "draw", scene))
    scene.render.engine = "CYCLES"
    scene.camera = None
    assert ("label", "Needs an active scene camera") in _draw(panels.RENDER_PT_ssr, "draw", scene)


def test_sidebar_offers_modes_debug_view_operators_and_overlay(addon):
    scene = _mirror_floor(*SMALL)
    log = _draw(panels.VIEW3D_PT_ssr, "draw", scene)
    assert ("prop", "comparison_mode", True, True) in log
    assert {entry[1] for entry in log if entry[0] == "prop"} >= {"debug_view", "show_overlay"}
    scene.ssr.comparison_mode = "CUBEMAP"  # the cubemap's centre belongs to the cubemap mode alone
    assert "probe_object" in {entry[1] for entry in _draw(panels.VIEW3D_PT_ssr, "draw", scene) if entry[0] == "prop"}
    scene.ssr.comparison_mode = "SSR"
    operators_drawn = {entry[1] for entry in log if entry[0] == "operator"}
    # Every operator but the presets, which sit in the Render properties panel; and the Live toggle.
    assert operators_drawn == ({cls.bl_idname for cls in operators.classes + live.classes}
                               - {"render.ssr_apply_preset"})
    assert {"debug_view", "live_resolution"} <= {entry[1] for entry in log if entry[0] == "prop"}
    scene.ssr.show_overlay = True  # its update redraws 3D views: none here
    scene.camera = None
    log = _draw(panels.VIEW3D_PT_ssr, "draw", scene)
    assert ("label", "Needs an active scene camera") in log
    assert ("operator", "render.ssr_render_frame", False) in log


# --- operators -------------------------------------------------------------------------------------------------

def _image_pixels(image):
    width, height = image.size
    pixels = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(pixels)
    return pixels.reshape(height, width, 4)[::-1]  # image order, row 0 at the top


@pytest.mark.slow
def test_render_frame_operator_makes_a_float_scene_linear_image(addon):
    scene = _mirror_floor(*SMALL)
    scene.ssr.comparison_mode = "SSR"
    assert bpy.ops.render.ssr_render_frame() == {"FINISHED"}
    image = bpy.data.images[result_image.RESULT_IMAGE]
    assert image.is_float and tuple(image.size) == SMALL
    assert image.colorspace_settings.name == "Linear Rec.709"
    final = _image_pixels(image)
    assert np.isfinite(final).all() and final[..., :3].max() > 0.1
    last_final, last_layers = result_image.last_result()
    np.testing.assert_array_equal(final, last_final)  # rows stored bottom-up

    layers = exr_channels(last_layers)
    scene.ssr.debug_view = "CONFIDENCE"  # switches the image without a new render
    confidence = _image_pixels(image)
    np.testing.assert_array_equal(confidence[..., :3], np.repeat(layers["SSR Confidence.V"][..., None], 3, axis=2))
    assert confidence[..., 0].max() > 0.5, "the mirror floor reflects the cubes: some rays hit"
    assert 0.0 <= confidence.min() and confidence.max() <= 1.0

    scene.ssr.debug_view = "HIT_UV"
    hit_uv = _image_pixels(image)
    np.testing.assert_array_equal(hit_uv[..., 0], layers["SSR Hit.U"])
    np.testing.assert_array_equal(hit_uv[..., 1], layers["SSR Hit.V"])
    assert not hit_uv[..., 2].any()

    scene.ssr.debug_view = "RAY_CLASS"
    assert set(np.unique(_image_pixels(image)[..., 0])) <= {0.0, 1.0, 2.0}

    assert gpu_passes._compiled
    ssr_addon.unregister()  # disabling the add-on releases what the render kept
    try:
        assert not gpu_passes._compiled, "the chain's compiled GPU shaders are released"
        assert result_image.last_result() is None
    finally:
        ssr_addon.register()  # for the fixture's teardown


@pytest.mark.slow
def test_operators_report_user_errors_without_a_traceback(addon):
    scene = _mirror_floor(*SMALL)
    objects_before = set(bpy.data.objects.keys())
    scene.camera = None
    with pytest.raises(RuntimeError, match="has no active camera") as error:
        bpy.ops.render.ssr_render_frame()
    assert "Traceback" not in str(error.value)
    assert set(bpy.data.objects.keys()) == objects_before
    with pytest.raises(RuntimeError, match="render an SSR frame first"):
        bpy.ops.render.ssr_setup_compositor()
    scene.ssr.comparison_mode = "PLANAR"
    scene.ssr.planar_object = bpy.data.objects["CubeRed"]
    add_camera(scene, (0.0, -7.0, 2.5), (0.0, 3.0, 0.3))
    with pytest.raises(RuntimeError, match="'CubeRed' is not a flat mesh"):
        bpy.ops.render.ssr_render_frame()


@pytest.mark.slow
def test_render_animation_writes_every_frame_in_background(addon, tmp_path):
    scene = _mirror_floor(*SMALL)
    scene.ssr.comparison_mode = "NONE"  # the frame loop is under test, not the chain
    scene.frame_start, scene.frame_end, scene.frame_current = 3, 4, 7
    scene.render.filepath = str(tmp_path / "anim" / "shot_")
    assert bpy.ops.render.ssr_render_animation() == {"FINISHED"}
    written = sorted(os.listdir(tmp_path / "anim"))
    # The output path's prefix names the frames, as F12 does; the command line's frame loop writes the report.
    assert written == [".ssr_records", "report.json"] + [f"shot_{n:04d}{suffix}" for n in (3, 4)
                                                         for suffix in (".exr", ".passes.exr", ".png")]
    with open(tmp_path / "anim" / "report.json", encoding="utf-8") as stream:
        report = json.load(stream)
    assert [entry["frame"] for entry in report["frames"]] == [3, 4] and report["fingerprint"]["mode"] == "NONE"
    assert scene.frame_current == 7


@pytest.mark.slow
def test_render_animation_decides_the_fallbacks_once_and_keeps_history(addon, tmp_path):
    """Under fallback=auto the shot's first frame chooses the levels and makes the captures;
    a still set's later frames reuse them and lean on the history, as the command line's do."""
    scene = _mirror_floor(*SMALL)
    scene.ssr.comparison_mode = "SSR"
    scene.ssr.cube_size = 16
    scene.eevee.taa_samples = 2
    scene.frame_start, scene.frame_end = 1, 2
    scene.render.filepath = str(tmp_path / "anim" / "shot_")
    assert bpy.ops.render.ssr_render_animation() == {"FINISHED"}
    with open(tmp_path / "anim" / "report.json", encoding="utf-8") as stream:
        first, second = json.load(stream)["frames"]
    assert first["captured"], "the mirror floor's sky lies above the frame: auto must capture"
    assert second["captured"] == [] and "fallback_choice" not in second["stages_ms"]
    assert second["iterations"] < first["iterations"]  # a frame with history settles at once


@pytest.mark.slow
def test_compositor_outputs_the_result_and_keeps_post_processing(addon, tmp_path):
    scene = _sculpture_scene()
    scene.render.engine = "BLENDER_WORKBENCH"  # the render itself is replaced: keep it cheap
    gradient = np.zeros(SMALL[::-1] + (4,), np.float32)
    gradient[..., 0] = np.linspace(0, 2, SMALL[0])[None, :]
    gradient[..., 1] = np.linspace(0, 1, SMALL[1])[:, None]
    gradient[..., 3] = 1
    result_image.publish_image(result_image.RESULT_IMAGE, gradient)
    assert bpy.ops.render.ssr_setup_compositor() == {"FINISHED"}
    composited = _render_composite(scene, tmp_path / "composited.exr")
    np.testing.assert_allclose(composited, gradient, atol=1e-3)

    # A tree that post-processes the render now post-processes the SSR result.
    tree = bpy.data.node_groups.new("Graded", "CompositorNodeTree")
    scene.compositing_node_group = tree
    render_layers = tree.nodes.new("CompositorNodeRLayers")
    exposure = tree.nodes.new("CompositorNodeExposure")
    exposure.inputs["Exposure"].default_value = 1.0
    output = tree.nodes.new("NodeGroupOutput")
    tree.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    tree.links.new(render_layers.outputs["Image"], exposure.inputs["Image"])
    tree.links.new(exposure.outputs["Image"], output.inputs[0])
    assert bpy.ops.render.ssr_setup_compositor() == {"FINISHED"}
    composited = _render_composite(scene, tmp_path / "graded.exr")
    np.testing.assert_allclose(composited[..., :3], gradient[..., :3] * 2.0, atol=2e-3)


def _render_composite(scene, path):
    """F12 render of SCENE, composited, as a float RGBA EXR read back in image order."""
    with TemporaryChanges() as changes:
        changes.set_all(scene.render.image_settings, media_type="IMAGE", file_format="OPEN_EXR",
                        color_mode="RGBA", color_depth="32")
        changes.set(scene.render, "filepath", str(path))
        changes.set(scene.render, "use_file_extension", False)
        bpy.ops.render.render(write_still=True, scene=scene.name)
    source = oiio.ImageInput.open(str(path))
    try:
        return np.asarray(source.read_image(0, 0, 0, 4, "float"))
    finally:
        source.close()


# --- baselines -------------------------------------------------------------------------------------------------

def _red_excess(rgba):
    return rgba[..., 0] - np.maximum(rgba[..., 1], rgba[..., 2])


def _blue_excess(rgba):
    return rgba[..., 2] - np.maximum(rgba[..., 0], rgba[..., 1])


@pytest.fixture(scope="module")
def sculpture_comparison():
    """The comparison sheet of the sculpture scene, cubemap around the sculpture: rendered once, read by two tests.

    Registers the add-on only while rendering, so other tests find it unregistered.
    """
    ssr_addon.register()
    try:
        scene = _sculpture_scene()
        scene.ssr.probe_object = bpy.data.objects["Sculpture"]
        state_before = (set(bpy.data.objects.keys()), len(bpy.data.lightprobes), scene.eevee.use_raytracing)
        assert bpy.ops.render.ssr_compare() == {"FINISHED"}
        state_after = (set(bpy.data.objects.keys()), len(bpy.data.lightprobes), scene.eevee.use_raytracing)
        sheet = _image_pixels(bpy.data.images[SHEET_IMAGE])

        def block(origins, directions):
            return _box_hit(origins, directions, BLOCK_LOW, BLOCK_HIGH)
        shows_block = _mirror_mask(scene, *SMALL, BASE_HALF, block, occluders=(block,))
        base = _mirror_mask(scene, *SMALL, BASE_HALF, lambda o, d: np.zeros(o.shape[:2]), occluders=(block,))
    finally:
        ssr_addon.unregister()
    width, height = SMALL
    columns = {mode: sheet[:, index * width:(index + 1) * width]
               for index, (mode, _, _) in enumerate(COMPARISON_MODES)}
    return SimpleNamespace(
        sheet=sheet, scene_restored=state_before == state_after, shows_block=shows_block, base=base,
        labels={mode: column[:-height] for mode, column in columns.items()},
        tiles={mode: column[-height:] for mode, column in columns.items()})


@pytest.mark.slow
def test_compare_sheet_shows_every_mode_labelled(sculpture_comparison):
    comparison = sculpture_comparison
    width, height = SMALL
    assert comparison.sheet.shape[1] == len(COMPARISON_MODES) * width
    assert np.isfinite(comparison.sheet).all() and comparison.scene_restored
    for mode, label in comparison.labels.items():
        assert 0.02 < (label[..., 0] > 0.5).mean() < 0.5, f"the {mode} label has no text"
    # The sculpture scene has no separate flat mesh: the planar tile is blank, the others show the block.
    assert not comparison.tiles["PLANAR"][..., :3].any()
    for mode in ("SSR", "CUBEMAP", "NONE"):
        assert _red_excess(comparison.tiles[mode]).max() > 1.0, f"the {mode} tile shows the glowing block"


@pytest.mark.slow
def test_cubemap_has_no_self_reflection_while_ssr_has(sculpture_comparison):
    tiles, shows_block = sculpture_comparison.tiles, sculpture_comparison.shows_block
    assert shows_block.sum() >= 20
    red = {mode: _red_excess(tiles[mode])[shows_block].mean() for mode in ("NONE", "CUBEMAP", "SSR")}
    assert red["SSR"] > 1.0, f"SSR reflects the sculpture's block in its own base: {red}"
    assert red["CUBEMAP"] < 0.1 and red["NONE"] < 0.1, f"no self-reflection without SSR: {red}"
    # The cubemap does capture the surroundings: the lantern beside the sculpture shows in its base.
    base = sculpture_comparison.base
    blue = {mode: _blue_excess(tiles[mode])[base].max() for mode in ("NONE", "CUBEMAP")}
    assert blue["CUBEMAP"] > blue["NONE"] + 0.3, f"the cubemap shows the lantern: {blue}"


BEACON_CENTRE, BEACON_RADIUS = (0.0, 10.0, 5.0), 1.0  # above the frame; its mirror image is in it


@pytest.mark.slow
def test_planar_baseline_matches_the_analytic_mirror_image_off_screen_too(addon):
    width, height = 96, 54
    scene = _mirror_floor(width, height)
    add_mesh(scene, "uv_sphere", "Beacon", BEACON_CENTRE, BEACON_RADIUS, principled(
        "Beacon", base_color=(0, 0, 0), roughness=1.0, emission=(0.1, 0.3, 1.0), emission_strength=8.0))
    floor = bpy.data.objects["Floor"]
    with TemporaryChanges() as changes:
        apply_baseline(scene, "planar", changes)  # picks the floor: the only flat mesh
        probes = [obj for obj in scene.objects if obj.type == "LIGHT_PROBE"]
        assert [probe.data.type for probe in probes] == ["PLANE"] and floor.hide_probe_plane
    assert not floor.hide_probe_plane and not any(obj.type == "LIGHT_PROBE" for obj in scene.objects)

    def beacon(origins, directions):
        return _sphere_hit(origins, directions, BEACON_CENTRE, BEACON_RADIUS)
    origins, directions = _pixel_rays(scene, width, height)
    assert not np.isfinite(beacon(origins, directions)).any(), "the beacon itself is off screen"
    expected = _mirror_mask(scene, width, height, 12.0, beacon)
    assert expected.sum() >= 50

    request = replace(operators.render_request(scene), samples=8)
    planar = render_mode(scene, "PLANAR", request)[0].final
    screen_trace_only, _ = render_frame(scene, replace(request, method="eevee-rt"))  # no plane probe
    found = _blue_excess(planar) > 1.5
    overlap = (found & expected).sum() / expected.sum()
    assert overlap > 0.7, f"the planar reflection covers {overlap:.0%} of the analytic mirror image"
    rows, columns = np.nonzero(found)
    expected_rows, expected_columns = np.nonzero(expected)
    assert abs(rows.mean() - expected_rows.mean()) < 1.5 and abs(columns.mean() - expected_columns.mean()) < 1.5
    assert (_blue_excess(screen_trace_only.final) > 1.5)[expected].mean() < 0.1, \
        "screen-space tracing alone cannot reflect what is off screen"


def _vertex_boxes(scene):
    """World bounds (low, high) of each rendered mesh, by name, from its evaluated vertices."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    boxes = {}
    for obj in scene.objects:
        if obj.type == "MESH" and not obj.hide_render:
            evaluated = obj.evaluated_get(depsgraph)
            matrix = np.array(evaluated.matrix_world)
            local = np.array([vertex.co for vertex in evaluated.data.vertices])
            world = local @ matrix[:3, :3].T + matrix[:3, 3]
            boxes[obj.name] = (world.min(axis=0), world.max(axis=0))
    return boxes


def _sphere_probe(scene, changes):
    apply_baseline(scene, "cubemap", changes)
    (probe,) = [obj for obj in scene.objects if obj.type == "LIGHT_PROBE"]
    assert probe.data.type == "SPHERE" and not scene.eevee.use_raytracing
    return probe


def _outside(point, box, margin=1e-3):
    low, high = box
    return bool(np.any(point < low - margin) or np.any(point > high + margin))


def test_default_cubemap_sits_in_free_space_at_eye_height(addon):
    """Where a level artist would put it: over the scene, at about the camera's height, in free space, with
    every object inside its influence. The old centre of the scene's bounds sat at a third of the camera's
    height above the mirror floor, where the marker's reflection swelled into a giant disc."""
    scene = _mirror_floor(*SMALL)
    boxes = _vertex_boxes(scene)
    camera_height = scene.camera.matrix_world.translation.z
    floor = bpy.data.objects["Floor"]
    with TemporaryChanges() as changes:
        probe = _sphere_probe(scene, changes)
        location = np.array(probe.location)
        assert all(_outside(location, box) for box in boxes.values()), location
        assert 0.5 * camera_height <= location[2] <= camera_height + 1e-6, location
        # The influence sphere (past its falloff band) holds every object standing on the floor.
        inner = probe.data.influence_distance * (1 - probe.data.falloff)
        for name, (low, high) in boxes.items():
            if name != "Floor":
                corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                                    for z in (low[2], high[2])])
                assert np.linalg.norm(corners - location, axis=1).max() <= inner, name
        assert probe.data.clip_end > np.linalg.norm(boxes["Floor"][1] - location)
        assert floor.hide_probe_sphere, "the floor is left out of its own reflection"
    assert not floor.hide_probe_sphere and not any(obj.type == "LIGHT_PROBE" for obj in scene.objects)

    # A pillar where the probe would go pushes it aside, not up through the roof; a room around the
    # camera is where the probe belongs, not an obstacle to climb out of.
    add_mesh(scene, "cube", "Pillar", (0.0, 0.0, 2.0), (0.4, 0.4, 2.0), principled("Pillar"))
    add_mesh(scene, "cube", "Room", (0.0, 0.0, 4.0), (12.0, 12.0, 4.0), principled("Room"))
    boxes = _vertex_boxes(scene)
    with TemporaryChanges() as changes:
        location = np.array(_sphere_probe(scene, changes).location)
    room = boxes.pop("Room")
    assert not _outside(location, room, margin=-1e-3), f"{location} left the room"
    assert all(_outside(location, box) for box in boxes.values()), location
    assert 0.5 * camera_height <= location[2] <= camera_height + 1e-6, location
    assert np.hypot(location[0], location[1]) < 1.0, f"{location}: beside the pillar, not across the room"


@pytest.mark.slow
def test_default_cubemap_shows_the_marker_misplaced_not_as_a_giant_disc(addon):
    """On the mirror floor the cubemap reflects the cubes and the marker, imperfectly: shifted and rescaled.
    The marker's true mirror image covers a known small area; its cubemap image may be a few times that, not
    the disc of the old capture point near the floor (5.4 times as large here), and each cube's reflection
    overlaps its true mirror image somewhat (the old point smeared them sideways, overlapping none)."""
    width, height = 128, 72
    scene = _mirror_floor(width, height)
    image = render_mode(scene, "CUBEMAP", replace(operators.render_request(scene), samples=4))[0].final
    origins, directions = _pixel_rays(scene, width, height)
    marker_centre, marker_radius = (0.0, 3.0, 1.2), 0.35  # test_scenes/mirror_floor.py

    def marker(o, d):
        return _sphere_hit(o, d, marker_centre, marker_radius)
    mirror_image = _mirror_mask(scene, width, height, 12.0, marker)
    assert mirror_image.sum() >= 30
    orange = (image[..., 0] > 1.0) & (image[..., 1] > 0.5 * image[..., 0]) & (image[..., 2] < 0.4 * image[..., 0])
    reflected = orange & ~np.isfinite(marker(origins, directions))  # not the marker itself
    assert 0 < reflected.sum() <= 3.5 * mirror_image.sum(), \
        f"the marker's reflection covers {reflected.sum()} pixels, its mirror image {mirror_image.sum()}"
    for name, x, excess in (("red", -2.2, _red_excess), ("blue", 2.2, _blue_excess)):
        def cube(o, d, x=x):
            return _box_hit(o, d, (x - 0.5, 4.5, 0.0), (x + 0.5, 5.5, 1.0))
        cube_mirror = _mirror_mask(scene, width, height, 12.0, cube)
        shown = (excess(image) > 0.05) & cube_mirror
        assert shown.sum() >= 0.05 * cube_mirror.sum(), f"the {name} cube's reflection misses its mirror image"


# --- the extension package -------------------------------------------------------------------------------------

INSTALL_AND_ENABLE = textwrap.dedent("""
    import importlib, json, sys
    import bpy
    import addon_utils
    module = "bl_ext.user_default.stochastic_ssr"
    bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo="user_default", enable_on_install=True)
    state = {"enabled": module in bpy.context.preferences.addons,
             "scene_property": hasattr(bpy.types.Scene, "ssr"),
             "operator": "ssr_render_frame" in dir(bpy.ops.render),
             "thickness": bpy.context.scene.ssr.thickness}
    # A render wrangler's entry point: the installed extension's command line, loading a .py scene.
    cli = importlib.import_module(module + ".ssr_addon.batch.cli")
    cli.main(["render", sys.argv[2], "--method", "none", "--resolution", "32x18", "--out", sys.argv[3]])
    state["enabled_after_cli"] = module in bpy.context.preferences.addons and hasattr(bpy.types.Scene, "ssr")
    # Every render operator of the installed add-on, on the scene the command line loaded.
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y, scene.eevee.taa_render_samples = 32, 18, 1
    scene.frame_start = scene.frame_end = scene.frame_current
    scene.render.filepath = sys.argv[3] + "/operators/take_"
    state["operators"] = {name: sorted(getattr(bpy.ops.render, name)(**kwargs)) for name, kwargs in (
        ("ssr_apply_preset", {"preset": "draft"}), ("ssr_render_frame", {}), ("ssr_setup_compositor", {}),
        ("ssr_compare", {}), ("ssr_render_animation", {}))}
    # What a render loads: none of the lab's measuring packages.
    state["lab_modules"] = sorted(name for name in sys.modules
                                  if name.split(".")[0] in ("lab", "matplotlib", "flip_evaluator", "skimage"))
    addon_utils.disable(module)
    state["disabled_cleanly"] = not hasattr(bpy.types.Scene, "ssr") and not hasattr(bpy.types, "RENDER_PT_ssr")
    print("STATE " + json.dumps(state))
""")


@pytest.mark.slow
def test_built_extension_installs_enables_and_disables(tmp_path):
    subprocess.run([sys.executable, BLENDER_EXT, "build", "--source-dir", REPO, "--output-dir", str(tmp_path)],
                   check=True, capture_output=True)
    (package,) = tmp_path.glob("stochastic_ssr-*.zip")
    names = set(zipfile.ZipFile(package).namelist())
    add_on_sources = {os.path.relpath(os.path.join(folder, name), REPO).replace(os.sep, "/")
                      for folder, _, files in os.walk(os.path.join(REPO, "ssr_addon"))
                      if "__pycache__" not in folder for name in files}
    assert any(name.endswith(".glsl") for name in add_on_sources)
    shipped_extras = {name for name in os.listdir(REPO) if name.startswith(("README", "LICENSE"))}
    assert {"LICENSE", "README.md"} <= shipped_extras, "the manifest's GPL-3.0 needs its text in the zip"
    assert names == {"__init__.py", "blender_manifest.toml"} | add_on_sources | shipped_extras
    assert not any(name.startswith(("lab/", "tests/", "test_scenes/")) for name in names), "the lab does not ship"

    user_dir = tmp_path / "user"
    script = tmp_path / "install.py"
    script.write_text(INSTALL_AND_ENABLE)
    result = subprocess.run([sys.executable, str(script), str(package), os.path.join(SCENES, "mirror_floor.py"),
                             str(tmp_path / "cli_out")], cwd=tmp_path, capture_output=True,
                            text=True, env={**os.environ, "BLENDER_USER_RESOURCES": str(user_dir)}, timeout=300)
    lines = [line for line in result.stdout.splitlines() if line.startswith("STATE ")]
    assert lines, result.stdout + result.stderr
    state = json.loads(lines[-1][len("STATE "):])
    finished = ["FINISHED"]
    assert state == {"enabled": True, "scene_property": True, "operator": True,
                     "thickness": pytest.approx(0.2), "enabled_after_cli": True, "disabled_cleanly": True,
                     "operators": dict.fromkeys(("ssr_apply_preset", "ssr_render_frame", "ssr_setup_compositor",
                                                 "ssr_compare", "ssr_render_animation"), finished),
                     "lab_modules": []}
    assert (tmp_path / "cli_out" / "frame_0001.exr").is_file()
    assert (tmp_path / "cli_out" / "operators" / "report.json").is_file()
    assert (user_dir / "extensions" / "user_default" / "stochastic_ssr" / "ssr_addon" / "core" / "shaders").is_dir()


@pytest.mark.slow
def test_the_compare_ssr_tile_is_exactly_a_ssr_render(addon):
    """compare's SSR tile used to capture a cubemap of its own as the fallback (a cream disc around
    the mirror floor's green box that `render --method ssr` never showed); now it is the same render."""
    scene = _mirror_floor(64, 36)
    request = replace(operators.render_request(scene), samples=4)
    lightprobes = len(bpy.data.lightprobes)
    tile = render_mode(scene, "SSR", request)[0].final
    assert len(bpy.data.lightprobes) == lightprobes
    rendered, _ = render_frame(scene, request)
    np.testing.assert_allclose(tile, rendered.final, atol=1e-4)
