"""Roughness and F0 AOVs of materials as artists build them: groups, mixes, other BSDFs, instances.

One render of a row of planes, each with one kind of material, checked against the
values each material was built with. Seen from above by an orthographic camera:
x in [-4, 4] and y in [-0.5, 1.5], 16 pixels per unit, row 0 at y = 1.5.
"""
import bpy
import numpy as np
import pytest

from ssr_addon.blender.render_passes import render_passes
from ssr_addon.blender.render_setup import decide_render

pytestmark = [pytest.mark.blender, pytest.mark.slow]

PIXELS_PER_UNIT = 16
PLANE = 0.9


def _pixel(x, y):
    return int((1.5 - y) * PIXELS_PER_UNIT), int((x + 4) * PIXELS_PER_UNIT)


def _plane(name, x, y, material):
    bpy.ops.mesh.primitive_plane_add(size=PLANE, location=(x, y, 0))
    plane = bpy.context.active_object
    plane.name = name
    plane.data.materials.append(material)
    return plane


def _material(name, build_surface):
    """A material whose surface is what BUILD_SURFACE(tree) returns (an output socket)."""
    material = bpy.data.materials.new(name)
    tree = material.node_tree
    tree.nodes.remove(tree.nodes["Principled BSDF"])
    tree.links.new(build_surface(tree), tree.nodes["Material Output"].inputs["Surface"])
    return material


def _node(tree, kind, **inputs):
    node = tree.nodes.new(kind)
    for name, value in inputs.items():
        node.inputs[name.replace("_", " ")].default_value = value
    return node


def _glossy(tree, grey, roughness, kind="ShaderNodeBsdfGlossy"):
    return _node(tree, kind, Color=(grey, grey, grey, 1), Roughness=roughness).outputs[0]


def _mix(tree, factor, a, b):
    mix = tree.nodes.new("ShaderNodeMixShader")
    if isinstance(factor, float):
        mix.inputs[0].default_value = factor
    else:
        tree.links.new(factor, mix.inputs[0])
    tree.links.new(a, mix.inputs[1])
    tree.links.new(b, mix.inputs[2])
    return mix.outputs[0]


def _add(tree, a, b):
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(a, add.inputs[0])
    tree.links.new(b, add.inputs[1])
    return add.outputs[0]


def _value(tree, value):
    node = tree.nodes.new("ShaderNodeValue")
    node.outputs[0].default_value = value
    return node.outputs[0]


def _grey_texture(tree, value):
    image = bpy.data.images.new(f"grey {value}", 4, 4)
    image.generated_color = (value, value, value, 1.0)
    image.colorspace_settings.name = "Non-Color"
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = image
    return texture.outputs["Color"]


def _group(name, build_inside):
    """A shader group with a float input "Roughness" and a shader output BUILD_INSIDE(tree, roughness) makes."""
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    group.interface.new_socket("Roughness", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    inputs, outputs = group.nodes.new("NodeGroupInput"), group.nodes.new("NodeGroupOutput")
    group.links.new(build_inside(group, inputs.outputs["Roughness"]), outputs.inputs["Shader"])
    return group


def _group_node(tree, group, roughness=None):
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    if roughness is not None:
        tree.links.new(roughness, node.inputs["Roughness"])
    return node.outputs["Shader"]


def _metal_inside(tree, roughness):
    bsdf = _node(tree, "ShaderNodeBsdfPrincipled", Base_Color=(0.8, 0.5, 0.2, 1), Metallic=1.0)
    tree.links.new(roughness, bsdf.inputs["Roughness"])
    return bsdf.outputs[0]


def _nested_groups():
    """A Principled BSDF inside a group inside a group, its roughness fed from outside both."""
    inner = _group("inner metal", _metal_inside)
    return _group("outer metal", lambda tree, roughness: _group_node(tree, inner, roughness))


def _metallic(tree, fresnel_type, roughness, **inputs):
    node = tree.nodes.new("ShaderNodeBsdfMetallic")
    node.fresnel_type = fresnel_type  # first: it decides which inputs exist
    node.inputs["Roughness"].default_value = roughness
    for name, value in inputs.items():
        node.inputs[name.replace("_", " ")].default_value = value
    return node.outputs[0]


def _generated_x(tree):
    """0 at the plane's left edge, 1 at its right edge."""
    split = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(tree.nodes.new("ShaderNodeTexCoord").outputs["Generated"], split.inputs[0])
    return split.outputs["X"]


def _collection_instance(x, y, material):
    """An empty instancing a collection that is not in the scene, holding a plane with MATERIAL."""
    collection = bpy.data.collections.new("instanced")
    bpy.ops.mesh.primitive_plane_add(size=PLANE)
    plane = bpy.context.active_object
    plane.data.materials.append(material)
    bpy.context.scene.collection.objects.unlink(plane)
    collection.objects.link(plane)
    empty = bpy.data.objects.new("instancer", None)
    empty.instance_type, empty.instance_collection = "COLLECTION", collection
    empty.location = (x, y, 0)
    bpy.context.scene.collection.objects.link(empty)


def _geometry_nodes_grid(x, y, material):
    """An object whose geometry nodes make a grid and give it MATERIAL (no material slot holds it)."""
    tree = bpy.data.node_groups.new("grid with material", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    grid = _node(tree, "GeometryNodeMeshGrid", Size_X=PLANE, Size_Y=PLANE)
    set_material = tree.nodes.new("GeometryNodeSetMaterial")
    set_material.inputs["Material"].default_value = material
    tree.links.new(grid.outputs["Mesh"], set_material.inputs["Geometry"])
    tree.links.new(set_material.outputs[0], tree.nodes.new("NodeGroupOutput").inputs[0])
    obj = bpy.data.objects.new("geometry nodes", bpy.data.meshes.new("empty"))
    obj.location = (x, y, 0)
    obj.modifiers.new("grid", "NODES").node_group = tree
    bpy.context.scene.collection.objects.link(obj)


def _linked_material(folder, roughness):
    """A Principled material linked from another .blend file (not editable in this one)."""
    material = bpy.data.materials.new("from library")
    material.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = roughness
    path = str(folder / "library.blend")
    bpy.data.libraries.write(path, {material}, fake_user=True)
    bpy.data.materials.remove(material)
    with bpy.data.libraries.load(path, link=True) as (_, linked):
        linked.materials = ["from library"]
    assert linked.materials[0].library is not None
    return linked.materials[0]


def _snapshot():
    """Every node tree as plain data: nodes, links, group interfaces and group node sockets."""
    trees = [(m.name_full, m.node_tree) for m in bpy.data.materials] + \
        [(g.name_full, g) for g in bpy.data.node_groups]
    return {name: (sorted((n.name, n.bl_idname, tuple(s.identifier for s in n.outputs)) for n in tree.nodes),
                   sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                          for l in tree.links),
                   [(i.name, i.item_type, getattr(i, "in_out", None)) for i in tree.interface.items_tree],
                   tree.interface.active_index)
            for name, tree in trees}


# Physical conductor Fresnel at normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2).
CONDUCTOR_N, CONDUCTOR_K = np.array([0.2, 0.9, 1.1]), np.array([3.0, 2.5, 2.0])
CONDUCTOR_F0 = ((CONDUCTOR_N - 1) ** 2 + CONDUCTOR_K ** 2) / ((CONDUCTOR_N + 1) ** 2 + CONDUCTOR_K ** 2)


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """(passes, node trees before, node trees after) of one render of the whole row."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    outer = _nested_groups()
    glossy_group = _group("glossy inside", lambda tree, _: _glossy(tree, 0.8, 0.25))
    toon = _material("toon", lambda tree: tree.nodes.new("ShaderNodeBsdfToon").outputs[0])
    rows = {
        0: [_material("nested groups", lambda t: _group_node(t, outer, _grey_texture(t, 0.3))),
            _material("mix", lambda t: _mix(t, 0.25, _glossy(t, 0.5, 0.2), _glossy(t, 0.9, 0.6))),
            _material("mix by texture", lambda t: _mix(t, _generated_x(t), _glossy(t, 1, 0.2), _glossy(t, 1, 0.6))),
            _material("add", lambda t: _add(t, _glossy(t, 0.3, 0.2),
                                            _glossy(t, 0.5, 0.6, "ShaderNodeBsdfAnisotropic"))),
            _material("glass", lambda t: _node(t, "ShaderNodeBsdfGlass", IOR=1.5, Roughness=0.15).outputs[0]),
            _material("metallic F82", lambda t: _metallic(t, "F82", 0.25, Base_Color=(0.9, 0.6, 0.3, 1))),
            _material("metallic physical", lambda t: _metallic(t, "PHYSICAL_CONDUCTOR", 0.1,
                                                               IOR=CONDUCTOR_N, Extinction=CONDUCTOR_K)),
            _material("refraction", lambda t: _node(t, "ShaderNodeBsdfRefraction", Roughness=0.1).outputs[0])],
        1: [toon, toon,
            _material("emission", lambda t: t.nodes.new("ShaderNodeEmission").outputs[0]),
            None, None,  # a collection instance and a geometry-nodes grid, placed below
            _linked_material(tmp_path_factory.mktemp("library"), 0.55),
            _material("same groups", lambda t: _group_node(t, outer, _value(t, 0.7))),
            _material("mix with a group", lambda t: _mix(t, 0.5, _node(t, "ShaderNodeBsdfDiffuse").outputs[0],
                                                         _group_node(t, glossy_group)))],
    }
    for y, materials in rows.items():
        for column, material in enumerate(materials):
            if material is not None:
                _plane(f"{material.name} {column}", column - 3.5, y, material)
    _collection_instance(-0.5, 1, _material("instanced", lambda t: _glossy(t, 0.5, 0.4)))
    _geometry_nodes_grid(0.5, 1, _material("geometry nodes", lambda t: _glossy(t, 0.5, 0.45)))
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = "ORTHO", 8.0
    camera.location = (0, 0.5, 5)
    scene.collection.objects.link(camera)
    scene.camera = camera
    before = _snapshot()
    size = (8 * PIXELS_PER_UNIT, 2 * PIXELS_PER_UNIT)
    passes = render_passes(scene, decide_render(scene, "eevee", samples=1, resolution=size))
    return passes, before, _snapshot()


def _at(passes, column, y):
    """(roughness, F0) at the centre of the plane in COLUMN (0 to 7) of row Y."""
    pixel = _pixel(column - 3.5, y)
    return passes.roughness[pixel], passes.f0[pixel]


@pytest.mark.parametrize("column, y, roughness, f0", [
    (0, 0, 0.3, (0.8, 0.5, 0.2)),  # metal Principled two groups deep, roughness from a texture outside
    (6, 1, 0.7, (0.8, 0.5, 0.2)),  # the same groups in another material, roughness 0.7 from outside
])
def test_groups_read_through_their_inputs(rendered, column, y, roughness, f0):
    _check(rendered[0], column, y, roughness, f0)


@pytest.mark.parametrize("column, y, roughness, f0", [
    # Mix by 0.25 of (F0 0.5, roughness 0.2) and (F0 0.9, roughness 0.6): F0 0.75 * 0.5 + 0.25 * 0.9,
    # roughness weighted by what each lobe reflects: (0.375 * 0.2 + 0.225 * 0.6) / (0.375 + 0.225).
    (1, 0, 0.35, 0.6),
    # Add of (F0 0.3, roughness 0.2) and an anisotropic (F0 0.5, roughness 0.6): F0 0.8,
    # roughness (0.3 * 0.2 + 0.5 * 0.6) / 0.8.
    (3, 0, 0.45, 0.8),
    # Half Diffuse, half a group holding a Glossy (F0 0.8, roughness 0.25): the diffuse
    # half reflects nothing, so the roughness is the glossy's and F0 halves.
    (7, 1, 0.25, 0.4),
])
def test_mix_and_add_shaders_combine_their_lobes(rendered, column, y, roughness, f0):
    _check(rendered[0], column, y, roughness, (f0,) * 3)


def test_mix_factor_from_a_texture(rendered):
    """Fac is the plane's generated x: roughness lerps 0.2 to 0.6 across it (equal F0s)."""
    passes = rendered[0]
    centre = 2 - 3.5  # column 2
    row = _pixel(centre, 0)[0]
    for column in range(_pixel(centre - 0.35, 0)[1], _pixel(centre + 0.35, 0)[1]):
        factor = ((column + 0.5) / PIXELS_PER_UNIT - 4 - (centre - PLANE / 2)) / PLANE
        assert passes.roughness[row, column] == pytest.approx(0.2 + 0.4 * factor, abs=0.02)
        assert passes.f0[row, column] == pytest.approx([1.0] * 3, abs=0.02)


@pytest.mark.parametrize("column, roughness, f0", [
    (4, 0.15, (0.04,) * 3),             # Glass, IOR 1.5: ((1.5 - 1) / (1.5 + 1))^2
    (5, 0.25, (0.9, 0.6, 0.3)),         # Metallic BSDF, F82 tint: its base colour
    (6, 0.1, tuple(CONDUCTOR_F0)),      # Metallic BSDF, physical conductor: from n and k
    (7, 1.0, (0.0,) * 3),               # Refraction: no reflection lobe, nothing for SSR
])
def test_other_bsdfs(rendered, column, roughness, f0):
    _check(rendered[0], column, 0, roughness, f0)


@pytest.mark.parametrize("column, roughness, f0", [
    (3, 0.4, (0.5,) * 3),       # a plane in a collection instanced by an empty
    (4, 0.45, (0.5,) * 3),      # a material given by a geometry nodes Set Material node
    (5, 0.55, (0.04,) * 3),     # a material linked from another .blend file
])
def test_instances_and_linked_materials(rendered, column, roughness, f0):
    _check(rendered[0], column, 1, roughness, f0)


def test_materials_without_specular_are_fully_rough(rendered):
    for column in (0, 1, 2):  # Toon (unreadable) twice, Emission (nothing to reflect)
        _check(rendered[0], column, 1, 1.0, (0.0,) * 3)


def test_an_unreadable_material_is_warned_about_once(rendered):
    warnings = rendered[0].material_warnings
    assert len(warnings) == 1, warnings
    assert "material 'toon'" in warnings[0] and "Toon BSDF" in warnings[0], warnings


def test_node_trees_are_exactly_as_before(rendered):
    _, before, after = rendered
    assert after == before


def _check(passes, column, y, roughness, f0):
    measured_roughness, measured_f0 = _at(passes, column, y)
    assert measured_roughness == pytest.approx(roughness, abs=0.02)
    np.testing.assert_allclose(measured_f0, f0, atol=0.02)
