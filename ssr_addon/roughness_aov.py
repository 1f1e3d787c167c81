"""Roughness as a render pass: a shader AOV wired into every material that needs one.

Blender has no roughness pass, so each material gets an AOV Output node fed by
whatever drives its BSDF's Roughness socket (a constant, a texture, a node
chain). Everything added is removed again through TemporaryChanges.

The AOV is a colour (roughness, coverage, 0): pixels no material wrote (objects
without a node material, the sky) read coverage 0 and are treated as fully
rough, so SSR leaves them alone. Dividing by coverage undoes the pixel filter's
averaging at anti-aliased edges.
"""
import bpy

AOV_NAME = "ssr_roughness"

# BSDFs whose "Roughness" drives the specular lobe SSR replaces.
_SPECULAR_BSDFS = {"BSDF_PRINCIPLED", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC"}


def add_roughness_aov(scene, view_layer, changes):
    """Declare the AOV on the view layer and wire it into every material in use."""
    aov = view_layer.aovs.add()
    aov.name = AOV_NAME
    aov.type = "COLOR"
    changes.on_restore(lambda: view_layer.aovs.remove(aov))
    for material in _materials_in_use(scene):
        _wire_material(material, changes)


def _materials_in_use(scene):
    seen = set()
    for obj in scene.objects:
        for slot in getattr(obj, "material_slots", ()):
            material = slot.material
            if material is not None and material.name_full not in seen:
                seen.add(material.name_full)
                yield material


def _wire_material(material, changes):
    tree = material.node_tree
    output = _active_surface_output(tree) if tree is not None else None
    if output is None:
        return  # nothing is shaded through nodes: coverage stays 0
    packed = tree.nodes.new("ShaderNodeCombineXYZ")
    aov_node = tree.nodes.new("ShaderNodeOutputAOV")
    aov_node.aov_name = AOV_NAME
    changes.on_restore(lambda: (tree.nodes.remove(aov_node), tree.nodes.remove(packed)))
    tree.links.new(packed.outputs["Vector"], aov_node.inputs["Color"])
    packed.inputs["Y"].default_value = 1.0
    roughness_input = packed.inputs["X"]
    roughness = _driving_roughness_socket(output)
    if roughness is None:
        roughness_input.default_value = 1.0  # no specular BSDF: nothing for SSR to replace
    elif roughness.is_linked:
        tree.links.new(roughness.links[0].from_socket, roughness_input)
    else:
        roughness_input.default_value = roughness.default_value


def _active_surface_output(tree):
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    active = [n for n in outputs if n.is_active_output] or outputs
    return active[0] if active else None


def _driving_roughness_socket(output):
    """The Roughness input of the first specular BSDF upstream of the surface output."""
    pending = [output.inputs["Surface"]]
    visited = set()
    while pending:
        socket = pending.pop(0)
        for link in socket.links:
            node = link.from_node
            if node.name in visited or link.is_muted:
                continue
            visited.add(node.name)
            if node.type in _SPECULAR_BSDFS and "Roughness" in node.inputs:
                return node.inputs["Roughness"]
            pending.extend(s for s in node.inputs if s.is_linked)
    return None
