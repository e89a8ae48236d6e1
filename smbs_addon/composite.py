"""The caustic layer back into Blender: one Image datablock, added in the compositor.

With ``export`` (the way in) this is one of the two core modules that import
``bpy``; nothing in the core imports either of them.

``apply_layer`` keeps exactly one Image and one set of our compositor nodes per
scene, however often it is called:

- No compositor yet: a node group of our own, Render Layers + caustics -> Add ->
  Group Output, becomes ``scene.compositing_node_group`` (Blender 5.0+).
- The user's own compositor: our Image node and an Add node go between whatever
  fed the Group Output and the output; none of their nodes is changed.
- Already set up: only the image is updated.

Our nodes, node group and image carry the custom property ``smbs_caustics`` so
they can be found again whatever they are called. ``remove_layer`` takes them
out and restores the link the user had. Blender 4.2-4.5 (``scene.node_tree``,
Composite and Mix RGB nodes) is handled by the same code paths, untested.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

TAG = "smbs_caustics"  # custom property: node role, True on our group, layer name on our image
TREE_NAME = "SMBS Caustics Compositing"
# Roles (the TAG value) of our nodes.
IMAGE, ADD, RENDER_LAYERS, OUTPUT = "image", "add", "render_layers", "output"

_LINEAR = ("Linear Rec.709", "Linear", "Linear BT.709")


# ---------------------------------------------------------------------------
# Image datablock


def _image_rgba(image) -> np.ndarray:
    """(H,W,3|4) top row first -> (H,W,4) float32 bottom row first, alpha 1."""
    img = np.asarray(image, dtype=np.float32)
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"caustic image must be (H, W, 3), got shape {img.shape}")
    h, w = img.shape[:2]
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = img[::-1, :, :3]
    return rgba


def _set_linear(img):
    for name in _LINEAR:
        try:
            img.colorspace_settings.name = name
            return
        except TypeError:
            continue


def _find_image(name):
    """Our image for the layer ``name`` (an image of the user's with that name is left alone)."""
    return next((img for img in bpy.data.images if img.get(TAG) == name), None)


def _new_image(name, w, h, replacing=None):
    """A new float image called ``name``; users of ``replacing`` move to it."""
    if replacing is not None:
        replacing.name = name + " (old)"
    img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
    if replacing is not None:
        replacing.user_remap(img)
        bpy.data.images.remove(replacing)
    img[TAG] = name
    return img


def _load_file(img, filepath, w, h) -> bool:
    """Point ``img`` at the EXR; False if it does not load at the expected size."""
    if img.packed_file:
        img.unpack(method='REMOVE')
    img.source = 'FILE'
    img.filepath = filepath
    img.reload()
    _set_linear(img)
    # Reading the size loads the file; has_data is only True after that.
    return tuple(img.size) == (w, h) and img.is_float and img.has_data


def _ensure_image(name, image, filepath):
    rgba = _image_rgba(image)
    h, w = rgba.shape[:2]
    img = _find_image(name)
    if img is None:
        img = _new_image(name, w, h)
    img.alpha_mode = 'STRAIGHT'
    if filepath and os.path.isfile(bpy.path.abspath(filepath)) and _load_file(img, filepath, w, h):
        # The EXR holds exactly these pixels; writing them again would only mark
        # the image modified (and Blender would offer to overwrite the EXR).
        return img
    # In-memory layer, packed (as EXR) so that it is saved with the blend file.
    if img.source != 'GENERATED' or not img.is_float or tuple(img.size) != (w, h):
        if img.packed_file and img.is_float and tuple(img.size) == (w, h):
            pass  # a layer packed by an earlier call: overwrite its pixels
        else:
            img = _new_image(name, w, h, replacing=img)
    _set_linear(img)
    img.pixels.foreach_set(rgba.ravel())
    img.update()
    img.file_format = 'OPEN_EXR'
    img.pack()
    return img


# ---------------------------------------------------------------------------
# Compositor


def _blender5():
    """Blender 5.0+: the compositor is a node group of its own (scene.compositing_node_group)."""
    return "compositing_node_group" in bpy.types.Scene.bl_rna.properties


def _scene_tree(scene, create):
    """(tree, owned) for the scene's compositor; (None, False) if it has none."""
    if _blender5():
        tree = scene.compositing_node_group
        if tree is None and create:
            tree = bpy.data.node_groups.new(TREE_NAME, "CompositorNodeTree")
            tree[TAG] = True
            tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
            scene.compositing_node_group = tree
        return tree, bool(tree is not None and tree.get(TAG))
    # Blender 4.2-4.5: the tree is embedded in the scene; switching nodes on adds
    # the default Render Layers -> Composite, which we then treat as the user's.
    if not scene.use_nodes and create:
        scene.use_nodes = True
        scene[TAG + "_enabled_nodes"] = True
    return (scene.node_tree if scene.use_nodes else None), False


def _ours(tree, role=None):
    return [n for n in tree.nodes if n.get(TAG) and (role is None or n.get(TAG) == role)]


def _output_node(tree):
    kinds = ("NodeGroupOutput", "CompositorNodeComposite")
    outputs = [n for n in tree.nodes if n.bl_idname in kinds]
    active = [n for n in outputs if getattr(n, "is_active_output", False)]
    return (active or outputs or [None])[0]


def _output_socket(node):
    sockets = [s for s in node.inputs if s.bl_idname != "NodeSocketVirtual" and s.enabled]
    colour = [s for s in sockets if s.type == 'RGBA']
    return (colour or sockets or [None])[0]


def _socket(sockets, identifier, index):
    for s in sockets:
        if s.identifier == identifier:
            return s
    return sockets[index]


def _add_sockets(node):
    """(A, B, Result) of our Add node, ShaderNodeMix (5.0) or CompositorNodeMixRGB (4.x)."""
    if node.bl_idname == "ShaderNodeMix":
        return (_socket(node.inputs, "A_Color", 6), _socket(node.inputs, "B_Color", 7),
                _socket(node.outputs, "Result_Color", 2))
    return node.inputs[1], node.inputs[2], node.outputs[0]


def _new_node(tree, bl_idname, role, label, location):
    node = tree.nodes.new(bl_idname)
    node[TAG] = role
    node.name = node.label = label
    node.location = location
    return node


def _new_add_node(tree, location):
    if _blender5():  # CompositorNodeMixRGB is gone; ShaderNodeMix works in compositor trees
        node = _new_node(tree, "ShaderNodeMix", ADD, "SMBS Caustics Add", location)
        node.data_type = 'RGBA'
        node.blend_type = 'ADD'
        node.clamp_result = False
        _socket(node.inputs, "Factor_Float", 0).default_value = 1.0
    else:
        node = _new_node(tree, "CompositorNodeMixRGB", ADD, "SMBS Caustics Add", location)
        node.blend_type = 'ADD'
        node.use_clamp = False
        node.inputs[0].default_value = 1.0
    return node


def _is_complete(img_node, add):
    a, b, result = _add_sockets(add)
    return (b.is_linked and b.links[0].from_node == img_node
            and result.is_linked and a.is_linked)


def _unlink_ours(tree):
    """Remove our nodes, reconnecting what fed our Add node to where it led."""
    for add in _ours(tree, ADD):
        a, _, result = _add_sockets(add)
        source = a.links[0].from_socket if a.is_linked else None
        targets = [link.to_socket for link in result.links]
        if source is not None and not source.node.get(TAG):
            for target in targets:
                if not target.node.get(TAG):
                    tree.links.new(source, target)
    for node in _ours(tree):
        if node.get(TAG) != OUTPUT:
            tree.nodes.remove(node)


def _ensure_nodes(tree, img):
    images, adds = _ours(tree, IMAGE), _ours(tree, ADD)
    if len(images) == 1 and len(adds) == 1 and _is_complete(images[0], adds[0]):
        images[0].image = img
        return
    _unlink_ours(tree)  # half-removed or duplicated by the user: start again

    out = _output_node(tree)
    if out is None:
        kind = "NodeGroupOutput" if _blender5() else "CompositorNodeComposite"
        out = _new_node(tree, kind, OUTPUT, "SMBS Caustics Output", (600.0, 0.0))
    if _blender5() and _output_socket(out) is None:
        tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    target = _output_socket(out)
    x, y = out.location

    source = target.links[0].from_socket if target.is_linked else None
    if source is None:
        rl = _new_node(tree, "CompositorNodeRLayers", RENDER_LAYERS, "SMBS Caustics Render Layers",
                       (x - 500.0, y))
        source = rl.outputs["Image"]
    add = _new_add_node(tree, (x - 200.0, y - 200.0))
    img_node = _new_node(tree, "CompositorNodeImage", IMAGE, "SMBS Caustics", (x - 500.0, y - 350.0))
    img_node.image = img
    a, b, result = _add_sockets(add)
    tree.links.new(source, a)
    tree.links.new(img_node.outputs["Image"], b)
    tree.links.new(result, target)


def apply_layer(bpy_scene, image, name="SMBS Caustics", filepath=None):
    """Show ``image`` (H,W,3 float32, top row first) as an added layer in the compositor.

    ``filepath``: the EXR already holding ``image``; the Image datablock then
    reads from it. Without one the pixels are packed into the blend file.
    Returns the Image datablock.
    """
    img = _ensure_image(name, image, filepath)
    tree, _ = _scene_tree(bpy_scene, create=True)
    _ensure_nodes(tree, img)
    return img


def has_layer(bpy_scene, name="SMBS Caustics") -> bool:
    """Is there a caustic layer (our image, or our nodes in the scene's compositor)?"""
    tree, _ = _scene_tree(bpy_scene, create=False)
    return _find_image(name) is not None or (tree is not None and bool(_ours(tree)))


def remove_layer(bpy_scene, name="SMBS Caustics"):
    """Take our nodes (or our whole node group) and image out again."""
    tree, owned = _scene_tree(bpy_scene, create=False)
    if tree is not None:
        # Our own group goes as a whole, unless the user has built on it since.
        if owned and all(n.get(TAG) or n.bl_idname == "NodeGroupOutput" for n in tree.nodes):
            bpy_scene.compositing_node_group = None
            if tree.users == 0:
                bpy.data.node_groups.remove(tree)
        else:
            _unlink_ours(tree)
            for node in _ours(tree, OUTPUT):
                if not any(s.is_linked for s in node.inputs):
                    tree.nodes.remove(node)
    if bpy_scene.get(TAG + "_enabled_nodes"):  # Blender 4.x: we switched nodes on
        bpy_scene.use_nodes = False
        del bpy_scene[TAG + "_enabled_nodes"]
    img = _find_image(name)
    if img is not None and img.users == 0:
        bpy.data.images.remove(img)
