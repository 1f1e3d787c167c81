"""The specular lobe that reaches a shader socket, computed by nodes added to the material.

`SpecularReader.read(surface)` walks upstream from a material output's Surface
through Mix Shader, Add Shader, reroute, muted and group nodes to the BSDFs, and
returns a Lobe: the roughness and F0 (each an output socket or a constant) of
what reflects there, or None where nothing reflective does (how lobes combine:
material_aovs). Every node and group socket it adds is registered with
TemporaryChanges for removal.

- A group's lobe leaves it through two outputs added to the group's interface
  for the render (removed after), built once per group however many materials
  or group nodes share it; roughness fed from outside through the group's
  inputs is therefore read as the group node is fed.
- BSDFs: Principled (its base layer: dielectric F0 from IOR, specular level
  and tint, mixed with Base Color by Metallic; coat and sheen are not read),
  Glossy and Anisotropic (Color), Metallic (Base Color with the F82 tint, the
  conductor Fresnel of IOR and Extinction with the physical one), Glass
  (((ior - 1) / (ior + 1))^2 tinted by Color, as EEVEE tints its reflection)
  and EEVEE's Specular BSDF (Specular).
- Shaders that reflect nothing SSR could replace (Diffuse, Emission,
  Refraction, which has no reflection lobe, Sheen, Transparent...) read as
  None. Any other shader node (Toon, Hair, scripts, a shader passed into a
  group through its inputs) is listed as unreadable and also read as None.
"""
from collections import namedtuple

import bpy

Lobe = namedtuple("Lobe", "roughness f0")

_NOT_REFLECTIVE = {"BSDF_DIFFUSE", "EMISSION", "BSDF_TRANSPARENT", "HOLDOUT", "BSDF_TRANSLUCENT",
                   "SUBSURFACE_SCATTERING", "BSDF_REFRACTION", "BSDF_SHEEN", "BSDF_RAY_PORTAL"}
_BLACK = (0.0, 0.0, 0.0, 1.0)
# Weight of an imaginary fully rough lobe in every weighted roughness: where no lobe
# reflects the mix reads 1, elsewhere it shifts the roughness by about 1e-6 / reflectance.
_EPSILON = 1e-6


class NodeBuilder:
    """Adds nodes to one tree, each registered for removal. Operands are output sockets or constants."""

    def __init__(self, tree, changes):
        self.tree, self.changes = tree, changes

    def node(self, kind, **properties):
        node = self.tree.nodes.new(kind)
        for name, value in properties.items():
            setattr(node, name, value)
        self.changes.on_restore(lambda: self.tree.nodes.remove(node))
        return node

    def feed(self, operand, socket):
        if isinstance(operand, bpy.types.NodeSocket):
            self.tree.links.new(operand, socket)
        else:
            socket.default_value = operand

    def value_of(self, socket):
        """What SOCKET reads: the output linked to it, or its constant."""
        link = _live_link(socket)
        if link is not None:
            return link.from_socket
        return socket.default_value if socket.type == "VALUE" else tuple(socket.default_value)

    def socket(self, operand):
        """OPERAND as an output socket, for where only a link will do."""
        if isinstance(operand, bpy.types.NodeSocket):
            return operand
        constant = self.node("ShaderNodeValue" if isinstance(operand, float) else "ShaderNodeRGB")
        constant.outputs[0].default_value = operand
        return constant.outputs[0]

    def math(self, operation, *operands, kind="ShaderNodeMath"):
        node = self.node(kind, operation=operation)
        for socket, operand in zip(node.inputs, operands):
            self.feed(operand, socket)
        return node.outputs[0]

    def vector_math(self, operation, *operands):
        return self.math(operation, *operands, kind="ShaderNodeVectorMath")

    def mix_color(self, factor, a, b, blend="MIX", clamp=False):
        """A over B by FACTOR (1 when None) with BLEND."""
        node = self.node("ShaderNodeMix", data_type="RGBA", blend_type=blend, clamp_result=clamp)
        for operand, identifier in ((1.0 if factor is None else factor, "Factor_Float"), (a, "A_Color"),
                                    (b, "B_Color")):
            self.feed(operand, _by_identifier(node.inputs, identifier))
        return _by_identifier(node.outputs, "Result_Color")

    def grey(self, colour):
        node = self.node("ShaderNodeRGBToBW")
        self.feed(colour, node.inputs["Color"])
        return node.outputs["Val"]


def _by_identifier(sockets, identifier):
    """One of SOCKETS by identifier (indexing goes by name, which several sockets can share)."""
    return next(socket for socket in sockets if socket.identifier == identifier)


def _live_link(socket):
    """The link SOCKET reads, None where it reads its own value."""
    return next((link for link in socket.links if link.is_valid and not link.is_muted), None)


class SpecularReader:
    """Reads the lobes reaching shader sockets of any number of materials in one render."""

    def __init__(self, changes):
        self.changes = changes
        self._unreadable = []  # the unknown shader nodes met by the read under way, read as None
        self._groups = {}      # (group, shader output) -> (identifiers of its lobe outputs or None, unreadable)

    def read(self, surface):
        """(the lobe reaching a material output's SURFACE input, the unknown shader nodes on the way)."""
        self._unreadable = []
        return self._lobe_into(surface), self._unreadable

    def _lobe_into(self, socket):
        """The lobe reaching the shader input SOCKET, or None."""
        link = _live_link(socket)
        if link is None or link.from_socket.type != "SHADER":
            return None  # nothing, or a colour linked in (shown as emission)
        return self._lobe_from(link.from_socket)

    def _lobe_from(self, output):
        node = output.node
        if node.mute or node.type == "REROUTE":
            through = next((link.from_socket for link in node.internal_links if link.to_socket == output), None)
            return None if through is None else self._lobe_into(through)
        if node.type == "GROUP":
            return self._group_lobe(node, output)
        build = NodeBuilder(node.id_data, self.changes)
        if node.type == "MIX_SHADER":
            return _mix(build, build.value_of(node.inputs[0]),
                        self._lobe_into(node.inputs[1]), self._lobe_into(node.inputs[2]))
        if node.type == "ADD_SHADER":
            return _add(build, self._lobe_into(node.inputs[0]), self._lobe_into(node.inputs[1]))
        if node.type in _BSDF_LOBES:
            return _BSDF_LOBES[node.type](build, node)
        if node.type not in _NOT_REFLECTIVE:
            self._unreadable.append(_describe(node))
        return None

    def _group_lobe(self, node, output):
        if node.node_tree is None:
            return None
        key = (node.node_tree.name_full, output.identifier)
        if key not in self._groups:  # read once; a later read through it inherits what it met
            outer, self._unreadable = self._unreadable, []
            self._groups[key] = (self._expose(node.node_tree, output.identifier), self._unreadable)
            self._unreadable = outer
        exposed, unreadable = self._groups[key]
        self._unreadable.extend(unreadable)
        if exposed is None:
            return None
        return Lobe(*(_by_identifier(node.outputs, identifier) for identifier in exposed))

    def _expose(self, group, identifier):
        """Identifiers of outputs added to GROUP that carry the lobe reaching its output IDENTIFIER."""
        group_output = next((n for n in group.nodes if n.type == "GROUP_OUTPUT" and n.is_active_output), None)
        lobe = None if group_output is None else self._lobe_into(_by_identifier(group_output.inputs, identifier))
        if lobe is None:
            return None
        build = NodeBuilder(group, self.changes)
        exposed = []
        for name, socket_type, value in (("ssr roughness", "NodeSocketFloat", lobe.roughness),
                                         ("ssr F0", "NodeSocketColor", lobe.f0)):
            item = group.interface.new_socket(name, in_out="OUTPUT", socket_type=socket_type)
            self.changes.on_restore(lambda item=item: group.interface.remove(item))
            group.links.new(build.socket(value), _by_identifier(group_output.inputs, item.identifier))
            exposed.append(item.identifier)
        return exposed


def _describe(node):
    group = node.id_data
    if node.type == "GROUP_INPUT":
        return f"a shader passed into group '{group.name}'"
    return f"{node.bl_label} '{node.name}'" + ("" if group.is_embedded_data else f" in group '{group.name}'")


def _mix(build, factor, a, b):
    """Mix Shader: the F0s mixed by FACTOR, the roughness weighted by what each side reflects."""
    if a is None and b is None:
        return None
    f0 = build.mix_color(factor, _BLACK if a is None else a.f0, _BLACK if b is None else b.f0)
    if a is None or b is None:
        return Lobe((a or b).roughness, f0)
    reflects_a = build.math("MULTIPLY", build.math("SUBTRACT", 1.0, factor), build.grey(a.f0))
    reflects_b = build.math("MULTIPLY", factor, build.grey(b.f0))
    return Lobe(_weighted_roughness(build, a.roughness, reflects_a, b.roughness, reflects_b), f0)


def _add(build, a, b):
    """Add Shader: the F0s summed (at most 1), the roughness weighted by what each side reflects."""
    if a is None or b is None:
        return a or b
    f0 = build.mix_color(None, a.f0, b.f0, blend="ADD", clamp=True)
    return Lobe(_weighted_roughness(build, a.roughness, build.grey(a.f0), b.roughness, build.grey(b.f0)), f0)


def _weighted_roughness(build, roughness_a, weight_a, roughness_b, weight_b):
    """(ra wa + rb wb + 1 e) / (wa + wb + e), e = _EPSILON."""
    numerator = build.math("MULTIPLY_ADD", roughness_a, weight_a,
                           build.math("MULTIPLY_ADD", roughness_b, weight_b, _EPSILON))
    return build.math("DIVIDE", numerator, build.math("ADD", build.math("ADD", weight_a, weight_b), _EPSILON))


def _dielectric_f0(build, ior_socket):
    ior = build.value_of(ior_socket)
    ratio = build.math("DIVIDE", build.math("SUBTRACT", ior, 1.0), build.math("ADD", ior, 1.0))
    return build.math("MULTIPLY", ratio, ratio)


def _principled(build, bsdf):
    inputs = bsdf.inputs
    level = build.math("MULTIPLY", build.value_of(inputs["Specular IOR Level"]), 2.0)
    scale = build.math("MINIMUM", build.math("MULTIPLY", _dielectric_f0(build, inputs["IOR"]), level), 1.0)
    dielectric = build.mix_color(None, scale, build.value_of(inputs["Specular Tint"]), blend="MULTIPLY")
    f0 = build.mix_color(build.value_of(inputs["Metallic"]), dielectric, build.value_of(inputs["Base Color"]))
    return Lobe(build.value_of(inputs["Roughness"]), f0)


def _glass(build, bsdf):
    f0 = build.mix_color(None, _dielectric_f0(build, bsdf.inputs["IOR"]), build.value_of(bsdf.inputs["Color"]),
                         blend="MULTIPLY")
    return Lobe(build.value_of(bsdf.inputs["Roughness"]), f0)


def _metallic(build, bsdf):
    if bsdf.fresnel_type == "F82":
        return _coloured("Base Color")(build, bsdf)
    # Conductor Fresnel at normal incidence: ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2), per channel.
    n, k = build.value_of(bsdf.inputs["IOR"]), build.value_of(bsdf.inputs["Extinction"])
    k_squared = build.vector_math("MULTIPLY", k, k)
    below, above = build.vector_math("SUBTRACT", n, (1.0,) * 3), build.vector_math("ADD", n, (1.0,) * 3)
    f0 = build.vector_math("DIVIDE", build.vector_math("MULTIPLY_ADD", below, below, k_squared),
                           build.vector_math("MULTIPLY_ADD", above, above, k_squared))
    return Lobe(build.value_of(bsdf.inputs["Roughness"]), f0)


def _coloured(colour):
    """Reads a BSDF whose F0 is its input COLOUR."""
    return lambda build, bsdf: Lobe(build.value_of(bsdf.inputs["Roughness"]), build.value_of(bsdf.inputs[colour]))


_BSDF_LOBES = {"BSDF_PRINCIPLED": _principled, "BSDF_GLOSSY": _coloured("Color"), "BSDF_METALLIC": _metallic,
               "BSDF_GLASS": _glass, "EEVEE_SPECULAR": _coloured("Specular")}
