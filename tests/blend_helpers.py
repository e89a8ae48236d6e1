"""Building small Blender scenes in tests (needs the bpy module: import after
``pytest.importorskip("bpy")``)."""
import bpy
import numpy as np


def material(name, node_type, color=None, **inputs):
    """A material whose output is one BSDF node of node_type, with its colour and inputs set."""
    mat = bpy.data.materials.new(name)
    nodes = mat.node_tree.nodes
    nodes.clear()
    node, out = nodes.new(node_type), nodes.new("ShaderNodeOutputMaterial")
    if color is not None:
        node.inputs["Color"].default_value = (*color, 1.0)
    for k, v in inputs.items():
        node.inputs[k].default_value = v
    mat.node_tree.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def plane(scene, name, size, mat, location, rotation=(0, 0, 0)):
    """A size x size square (local +Z up) linked into scene."""
    s = size / 2
    me = bpy.data.meshes.new(name)
    me.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    me.materials.append(mat)
    ob = bpy.data.objects.new(name, me)
    ob.location, ob.rotation_euler = location, rotation
    scene.collection.objects.link(ob)
    return ob


def layer_image(h=4, w=6, value=1.0):
    """A caustic layer (H,W,3) whose top row is red and bottom row blue: orientation shows."""
    img = np.zeros((h, w, 3), np.float32)
    img[0] = (value, 0.0, 0.0)  # top row red
    img[-1] = (0.0, 0.0, value)  # bottom row blue
    return img


def image_pixels(image):
    """An Image datablock's pixels (H,W,4), bottom row first as Blender keeps them."""
    w, h = image.size
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    return buf.reshape(h, w, 4)


def our_nodes(tree, role):
    """The compositor nodes of ours (composite.TAG) of one role."""
    return [n for n in tree.nodes if n.get("smbs_caustics") == role]


def users_compositor(scene):
    """A compositor of the user's own, Render Layers -> Blur -> Group Output, as the scene's:
    (tree, render layers, blur, output)."""
    tree = bpy.data.node_groups.new("Mine", "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    rl = tree.nodes.new("CompositorNodeRLayers")
    blur = tree.nodes.new("CompositorNodeBlur")
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(rl.outputs["Image"], blur.inputs["Image"])
    tree.links.new(blur.outputs["Image"], out.inputs[0])
    scene.compositing_node_group = tree
    return tree, rl, blur, out
