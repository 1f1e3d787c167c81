"""A compositor node tree that outputs an image (the "SSR Result"), keeping the user's
post-processing."""
import bpy

RESULT_NODE = "SSR Result"  # name of the compositor Image node setup_compositor manages


def setup_compositor(scene, image):
    """Make the scene's compositor output IMAGE; returns the node tree.

    Where the tree already takes the render from a Render Layers node, those
    links are moved to the image, so the user's own post-processing now works
    on the SSR result; otherwise the image goes straight to the group output.
    """
    tree = scene.compositing_node_group
    if tree is None:
        tree = bpy.data.node_groups.new("SSR Compositing", "CompositorNodeTree")
        scene.compositing_node_group = tree
    source = tree.nodes.get(RESULT_NODE)
    if source is None:
        source = tree.nodes.new("CompositorNodeImage")
        source.name = source.label = RESULT_NODE
    source.image = image
    render_targets = [link.to_socket for link in tree.links
                      if link.from_node.bl_idname == "CompositorNodeRLayers" and link.from_socket.name == "Image"]
    for target in render_targets:
        tree.links.new(source.outputs["Image"], target)
    if not render_targets:
        tree.links.new(source.outputs["Image"], _group_output_socket(tree))
    scene.render.use_compositing = True
    return tree


def _group_output_socket(tree):
    """The first colour output of the tree's Group Output node, both created when missing."""
    if not any(item.item_type == "SOCKET" and item.in_out == "OUTPUT" for item in tree.interface.items_tree):
        tree.interface.new_socket(name="Image", in_out="OUTPUT", socket_type="NodeSocketColor")
    output = next((node for node in tree.nodes if node.bl_idname == "NodeGroupOutput"), None)
    if output is None:
        output = tree.nodes.new("NodeGroupOutput")
    return output.inputs[0]
