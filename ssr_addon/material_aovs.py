"""Roughness and F0 as render passes: shader AOVs wired into every material that needs them.

Blender has no roughness or F0 pass, so each material gets AOV Output nodes fed
by whatever drives its specular BSDF's sockets (constants, textures, node
chains). Everything added is removed again through TemporaryChanges.

- ROUGHNESS_AOV is a colour (roughness, coverage, 0): pixels no material wrote
  (objects without a node material, the sky) read coverage 0 and are treated
  as fully rough, so SSR leaves them alone. Dividing by coverage undoes the
  pixel filter's averaging at anti-aliased edges.
- F0_AOV is the specular reflectance at normal incidence, which the DFG table
  turns into the FG term: for the Principled BSDF
  mix(((ior - 1) / (ior + 1))^2 * 2 * specular_ior_level * specular_tint, base_color, metallic),
  for the Glossy and Metallic BSDFs their colour.
"""
ROUGHNESS_AOV = "ssr_roughness"
F0_AOV = "ssr_f0"

# BSDFs whose "Roughness" drives the specular lobe SSR replaces.
_SPECULAR_BSDFS = {"BSDF_PRINCIPLED", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC"}


def add_material_aovs(scene, view_layer, changes):
    """Declare the AOVs on the view layer and wire them into every material in use."""
    for name in (ROUGHNESS_AOV, F0_AOV):
        aov = view_layer.aovs.add()
        aov.name = name
        aov.type = "COLOR"
        changes.on_restore(lambda aov=aov: view_layer.aovs.remove(aov))
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


class _NodeBuilder:
    """Adds nodes to one tree, each registered for removal."""

    def __init__(self, tree, changes):
        self.tree, self.changes = tree, changes

    def node(self, kind, **properties):
        node = self.tree.nodes.new(kind)
        for name, value in properties.items():
            setattr(node, name, value)
        self.changes.on_restore(lambda: self.tree.nodes.remove(node))
        return node

    def value_of(self, socket):
        """An output socket carrying SOCKET's value: what feeds it, or its constant."""
        if socket.is_linked:
            return socket.links[0].from_socket
        if socket.type == "RGBA":
            constant = self.node("ShaderNodeRGB")
        else:
            constant = self.node("ShaderNodeValue")
        constant.outputs[0].default_value = socket.default_value
        return constant.outputs[0]

    def math(self, operation, a, b):
        node = self.node("ShaderNodeMath", operation=operation)
        for slot, operand in enumerate((a, b)):
            if isinstance(operand, float):
                node.inputs[slot].default_value = operand
            else:
                self.tree.links.new(operand, node.inputs[slot])
        return node.outputs[0]

    def mix_color(self, factor, a, b, blend="MIX"):
        node = self.node("ShaderNodeMix", data_type="RGBA", blend_type=blend)
        node.inputs["Factor"].default_value = 1.0
        for socket, operand in ((node.inputs["Factor"], factor), (node.inputs[6], a), (node.inputs[7], b)):
            if operand is not None:
                self.tree.links.new(operand, socket)
        return node.outputs[2]

    def aov(self, name, source):
        output = self.node("ShaderNodeOutputAOV", aov_name=name)
        self.tree.links.new(source, output.inputs["Color"])


def _wire_material(material, changes):
    tree = material.node_tree
    output = _active_surface_output(tree) if tree is not None else None
    if output is None:
        return  # nothing is shaded through nodes: coverage stays 0
    build = _NodeBuilder(tree, changes)
    bsdf = _specular_bsdf(output)
    packed = build.node("ShaderNodeCombineXYZ")
    packed.inputs["Y"].default_value = 1.0
    build.aov(ROUGHNESS_AOV, packed.outputs["Vector"])
    if bsdf is None:
        packed.inputs["X"].default_value = 1.0  # no specular BSDF: nothing for SSR to replace
        return
    tree.links.new(build.value_of(bsdf.inputs["Roughness"]), packed.inputs["X"])
    build.aov(F0_AOV, _f0_socket(build, bsdf))


def _f0_socket(build, bsdf):
    if bsdf.type != "BSDF_PRINCIPLED":
        colour = bsdf.inputs["Base Color"] if "Base Color" in bsdf.inputs else bsdf.inputs["Color"]
        return build.value_of(colour)
    ior = build.value_of(bsdf.inputs["IOR"])
    ratio = build.math("DIVIDE", build.math("SUBTRACT", ior, 1.0), build.math("ADD", ior, 1.0))
    level = build.math("MULTIPLY", build.value_of(bsdf.inputs["Specular IOR Level"]), 2.0)
    scale = build.math("MINIMUM", build.math("MULTIPLY", build.math("MULTIPLY", ratio, ratio), level), 1.0)
    # scale * tint: a multiply-blend with factor 1 of the grey scale and the tint colour.
    dielectric = build.mix_color(None, scale, build.value_of(bsdf.inputs["Specular Tint"]), blend="MULTIPLY")
    return build.mix_color(build.value_of(bsdf.inputs["Metallic"]), dielectric,
                           build.value_of(bsdf.inputs["Base Color"]))


def _active_surface_output(tree):
    outputs = [n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    active = [n for n in outputs if n.is_active_output] or outputs
    return active[0] if active else None


def _specular_bsdf(output):
    """The first specular BSDF upstream of the surface output."""
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
                return node
            pending.extend(s for s in node.inputs if s.is_linked)
    return None
