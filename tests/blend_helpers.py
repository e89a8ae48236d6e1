"""Building small Blender scenes in tests (needs the bpy module: import after
``pytest.importorskip("bpy")``)."""
import bpy


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
