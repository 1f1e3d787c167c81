"""Roughness and F0 as render passes: shader AOVs wired into every material in use.

Blender has no roughness or F0 pass, so each material gets AOV Output nodes fed
by what its surface's specular lobe reads (constants, textures, node chains,
through groups and shader mixes: see specular_lobes). Everything added is
removed again through TemporaryChanges.

- ROUGHNESS_AOV is a colour (roughness, coverage, view-axis depth): pixels no
  material wrote (objects without a node material, the sky) read coverage 0 and
  are treated as fully rough, so SSR leaves them alone. Dividing by coverage
  undoes the pixel filter's averaging at anti-aliased edges. The depth spares a
  viewport capture its Position draw (viewport_capture).
- F0_AOV is the specular reflectance at normal incidence, which the DFG table
  turns into the FG term.
- One roughness cannot describe two lobes. A Mix Shader's F0 is the mix of its
  sides' F0s; an Add Shader's their sum, at most 1. The roughness of either is
  the mean of the sides' roughness weighted by what each side reflects (its
  share of the mix times the grey value of its F0): a smooth lobe mixed half
  and half with an equally bright rough one reads halfway, a dim rough lobe
  barely changes a bright smooth one, and a side that reflects nothing
  (Diffuse, Emission, Refraction) only scales the F0. A surface that reflects
  nothing reads fully rough with F0 0: SSR leaves it alone.
- Materials in use are those on the scene's objects and those the depsgraph
  evaluates: collection instances, geometry nodes' Set Material. The nodes go
  into the original data-blocks; materials and groups linked from a library
  are edited too (Blender allows it at run time; nothing is saved).
- A shader node whose reflection cannot be read (Toon, Hair, scripts) counts
  as reflecting nothing; `add_material_aovs` returns one warning per material
  holding one, naming them. A material that simply reflects nothing gets none.
"""
import bpy

from .specular_lobes import NodeBuilder, SpecularReader

ROUGHNESS_AOV = "ssr_roughness"
F0_AOV = "ssr_f0"


def add_material_aovs(scene, view_layer, changes):
    """Declare the AOVs on VIEW_LAYER and wire them into every material in use for
    the scene's render engine. Returns the warnings, one line per unreadable material."""
    for name in (ROUGHNESS_AOV, F0_AOV):
        aov = view_layer.aovs.add()
        aov.name = name
        aov.type = "COLOR"
        changes.on_restore(lambda aov=aov: view_layer.aovs.remove(aov))
    target = "CYCLES" if scene.render.engine == "CYCLES" else "EEVEE"
    reader = SpecularReader(changes)
    warnings = []
    for material in _materials_in_use(scene, view_layer):
        unreadable = _wire_material(material, target, reader, changes)
        if unreadable:
            warnings.append(f"material '{material.name}': cannot read the reflection of "
                            f"{', '.join(dict.fromkeys(unreadable))}; assumed it reflects nothing "
                            "(fully rough, no SSR there)")
    return warnings


def _materials_in_use(scene, view_layer):
    """The original data-blocks of the materials on the scene's objects and of those the
    depsgraph evaluates (collection instances, Set Material nodes), in a stable order.
    The slots are read too: objects hidden in the viewport are missing from the view
    layer's depsgraph, which is the viewport's."""
    view_layer.update()  # builds and evaluates the depsgraph of a view layer never shown
    materials = [slot.material for obj in scene.objects for slot in getattr(obj, "material_slots", ())]
    materials += [data.original for data in view_layer.depsgraph.ids if isinstance(data, bpy.types.Material)]
    return {material.name_full: material for material in materials if material is not None}.values()


def _wire_material(material, target, reader, changes):
    """Wire the AOVs into MATERIAL; returns the shader nodes it could not read."""
    tree = material.node_tree
    output = tree.get_output_node(target) if tree is not None else None
    if output is None:
        return []  # nothing is shaded through nodes: coverage stays 0
    lobe, unreadable = reader.read(output.inputs["Surface"])
    build = NodeBuilder(tree, changes)
    packed = build.node("ShaderNodeCombineXYZ")
    build.feed(1.0 if lobe is None else lobe.roughness, packed.inputs["X"])
    packed.inputs["Y"].default_value = 1.0
    build.feed(build.node("ShaderNodeCameraData").outputs["View Z Depth"], packed.inputs["Z"])
    _aov(build, ROUGHNESS_AOV, packed.outputs["Vector"])
    if lobe is not None:
        _aov(build, F0_AOV, lobe.f0)
    return unreadable


def _aov(build, name, value):
    build.feed(value, build.node("ShaderNodeOutputAOV", aov_name=name).inputs["Color"])
