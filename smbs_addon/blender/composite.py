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

Receivers whose colour is a texture: the bake's albedo-free part ``per_albedo``
is multiplied by the render's own Diffuse Color pass (which holds the albedo
pixel by pixel) and added too. It is a second Image (``"<name> per Albedo"``),
a Render Layers node of ours, a Multiply and a second Add that feed our Add's
second input; so the only links to the user's nodes stay those of our Add, and
taking our nodes out restores the user's compositor the same way with or
without it. The view layer's Diffuse Color pass is switched on for it (and off
again only if we switched it on, recorded in ``scene[TAG + "_enabled_diffcol"]``).

Our nodes, node group and images carry the custom property ``smbs_caustics`` so
they can be found again whatever they are called. ``remove_layer`` takes them
out and restores the link the user had. Blender 4.2-4.5 (``scene.node_tree``,
Composite and Mix RGB nodes) is handled by the same code paths, untested.
"""
from __future__ import annotations

import os

import bpy
import numpy as np

from ..io.sequence import fill_frame

TAG = "smbs_caustics"  # custom property: node role, True on our group, layer name on our image
TREE_NAME = "SMBS Caustics Compositing"
# Roles (the TAG value) of our nodes.
IMAGE, ADD, RENDER_LAYERS, OUTPUT = "image", "add", "render_layers", "output"
# ... and of the per-albedo part: its image, our Render Layers node for the Diffuse Color pass,
# per_albedo x Diffuse Color, and the Add of that to IMAGE (which feeds ADD's second input).
ALBEDO_IMAGE, DIFFUSE_COLOR, MULTIPLY, ALBEDO_ADD = "albedo_image", "diffuse_color", "multiply", "albedo_add"
ALBEDO_ROLES = (ALBEDO_IMAGE, DIFFUSE_COLOR, MULTIPLY, ALBEDO_ADD)
ENABLED_DIFFCOL = TAG + "_enabled_diffcol"  # scene property: the view layer we switched the pass on for
_DIFFUSE_COLOR_OUTPUTS = ("Diffuse Color", "DiffCol")  # Render Layers output, Blender 5.0 / 4.x

_LINEAR = ("Linear Rec.709", "Linear", "Linear BT.709")
SEQUENCE = TAG + "_sequence"  # our image's property for a frame range: {pattern (a # run), first, last}


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


def _new_add_node(tree, location, role=ADD, label="SMBS Caustics Add", blend='ADD'):
    """A Mix node of ours (Add, or Multiply), factor 1, unclamped: (A, B, Result) as _add_sockets."""
    if _blender5():  # CompositorNodeMixRGB is gone; ShaderNodeMix works in compositor trees
        node = _new_node(tree, "ShaderNodeMix", role, label, location)
        node.data_type = 'RGBA'
        node.blend_type = blend
        node.clamp_result = False
        _socket(node.inputs, "Factor_Float", 0).default_value = 1.0
    else:
        node = _new_node(tree, "CompositorNodeMixRGB", role, label, location)
        node.blend_type = blend
        node.use_clamp = False
        node.inputs[0].default_value = 1.0
    return node


def _from(socket):
    """The node feeding ``socket``, or None."""
    return socket.links[0].from_node if socket.is_linked else None


def _image_source(img_node, add):
    """The node of ours feeding our Add's second input, if it brings the image: the image node,
    or our per-albedo Add whose first input is the image node. None otherwise."""
    node = _from(_add_sockets(add)[1])
    if node == img_node:
        return node
    if node is not None and node.get(TAG) == ALBEDO_ADD and _from(_add_sockets(node)[0]) == img_node:
        return node
    return None


def _is_complete(img_node, add):
    a, _, result = _add_sockets(add)
    return _image_source(img_node, add) is not None and result.is_linked and a.is_linked


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


def _ensure_nodes(tree, img, albedo=None):
    """Our nodes, updated in place if they are all there; ``albedo`` as for _ensure_albedo_nodes."""
    images, adds = _ours(tree, IMAGE), _ours(tree, ADD)
    if len(images) == 1 and len(adds) == 1 and _is_complete(images[0], adds[0]):
        images[0].image = img
        _ensure_albedo_nodes(tree, images[0], adds[0], albedo)
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
    _ensure_albedo_nodes(tree, img_node, add, albedo)


def _diffuse_color_output(rl):
    """The Render Layers node's Diffuse Color output (by iterating: a disabled output is not
    found by name), or None."""
    return next((s for s in rl.outputs if s.identifier in _DIFFUSE_COLOR_OUTPUTS), None)


def _albedo_complete(tree, img_node, add):
    """Our per-albedo nodes, one of each, linked as _ensure_albedo_nodes links them: a dict
    role -> node, or None."""
    parts = {role: _ours(tree, role) for role in ALBEDO_ROLES}
    if any(len(nodes) != 1 for nodes in parts.values()):
        return None
    nodes = {role: found[0] for role, found in parts.items()}
    sum_a, sum_b, _ = _add_sockets(nodes[ALBEDO_ADD])
    mul_a, mul_b, _ = _add_sockets(nodes[MULTIPLY])
    ok = (_image_source(img_node, add) == nodes[ALBEDO_ADD] and _from(sum_a) == img_node
          and _from(sum_b) == nodes[MULTIPLY] and _from(mul_a) == nodes[ALBEDO_IMAGE]
          and mul_b.is_linked and mul_b.links[0].from_socket == _diffuse_color_output(nodes[DIFFUSE_COLOR]))
    return nodes if ok else None


def _ensure_albedo_nodes(tree, img_node, add, albedo):
    """``albedo``: None, or (Image, scene, view layer name). With it, our Add's second input is
    image + albedo image x that view layer's Diffuse Color; without, the image alone and our
    per-albedo nodes are gone. Updated in place when they are all there."""
    b = _add_sockets(add)[1]
    nodes = _albedo_complete(tree, img_node, add) if albedo is not None else None
    if nodes is not None:
        nodes[ALBEDO_IMAGE].image = albedo[0]
        return
    for role in ALBEDO_ROLES:
        for node in _ours(tree, role):
            tree.nodes.remove(node)
    if albedo is None:
        if _from(b) != img_node:
            tree.links.new(img_node.outputs["Image"], b)
        return
    albedo_img, scene, layer = albedo
    x, y = img_node.location
    albedo_node = _new_node(tree, "CompositorNodeImage", ALBEDO_IMAGE, "SMBS Caustics per Albedo",
                            (x - 300.0, y - 250.0))
    albedo_node.image = albedo_img
    rl = _new_node(tree, "CompositorNodeRLayers", DIFFUSE_COLOR, "SMBS Caustics Diffuse Color",
                   (x - 300.0, y - 550.0))
    rl.scene = scene  # not the context's scene: apply_layer may be called for another
    rl.layer = layer
    mul = _new_add_node(tree, (x, y - 350.0), MULTIPLY, "SMBS Caustics x Diffuse Color", 'MULTIPLY')
    total = _new_add_node(tree, (x + 200.0, y - 150.0), ALBEDO_ADD, "SMBS Caustics Add per Albedo")
    mul_a, mul_b, mul_result = _add_sockets(mul)
    sum_a, sum_b, sum_result = _add_sockets(total)
    tree.links.new(albedo_node.outputs["Image"], mul_a)
    tree.links.new(_diffuse_color_output(rl), mul_b)
    tree.links.new(img_node.outputs["Image"], sum_a)
    tree.links.new(mul_result, sum_b)
    tree.links.new(sum_result, b)


def _render_view_layer(scene):
    """The view layer our Render Layers node reads: the first one rendered, else the first."""
    return next((vl for vl in scene.view_layers if vl.use), scene.view_layers[0])


def _albedo_view_layer(tree, scene):
    """The view layer for the Diffuse Color pass: the one our Render Layers node already reads
    (the user may have chosen another), else _render_view_layer."""
    for rl in _ours(tree, DIFFUSE_COLOR):
        if rl.scene == scene and rl.layer in scene.view_layers:
            return scene.view_layers[rl.layer]
    return _render_view_layer(scene)


def _switch_diffuse_color(scene, layer_name):
    """The Diffuse Color pass on for the view layer ``layer_name`` (None: for none of ours).

    Only a pass we switched on is recorded, and only that one is switched off again (when
    ``layer_name`` is another view layer or None): a pass the user had on stays on.
    """
    ours = scene.get(ENABLED_DIFFCOL)
    if ours is not None and ours != layer_name:
        vl = scene.view_layers.get(ours)
        if vl is not None:
            vl.use_pass_diffuse_color = False
        del scene[ENABLED_DIFFCOL]
    vl = scene.view_layers.get(layer_name) if layer_name else None
    if vl is not None and not vl.use_pass_diffuse_color:
        vl.use_pass_diffuse_color = True
        scene[ENABLED_DIFFCOL] = vl.name


def diffuse_color_switched_on(bpy_scene):
    """The name of the view layer whose Diffuse Color pass apply_layer switched on, or None."""
    return bpy_scene.get(ENABLED_DIFFCOL)


def albedo_image_name(name="SMBS Caustics") -> str:
    return f"{name} per Albedo"


def _remove_image(name):
    img = _find_image(name)
    if img is not None and img.users == 0:
        bpy.data.images.remove(img)


def apply_layer(bpy_scene, image, name="SMBS Caustics", filepath=None, per_albedo=None,
                per_albedo_filepath=None):
    """Show ``image`` (H,W,3 float32, top row first) as an added layer in the compositor.

    ``filepath``: the EXR already holding ``image``; the Image datablock then
    reads from it. Without one the pixels are packed into the blend file.

    ``per_albedo`` (H,W,3, the caustic on textured receivers divided by their
    albedo; ``per_albedo_filepath`` as ``filepath``): multiplied by the render's
    Diffuse Color pass, which is switched on for the purpose
    (diffuse_color_switched_on tells for which view layer), and added as well.
    Without it, the per-albedo part of an earlier call goes again.
    Returns the Image datablock of ``image``.
    """
    if per_albedo is not None and np.shape(per_albedo)[:2] != np.shape(image)[:2]:
        raise ValueError(f"per_albedo must be the size of the image {np.shape(image)[:2]}, "
                         f"got shape {np.shape(per_albedo)}")
    img = _ensure_image(name, image, filepath)
    tree, _ = _scene_tree(bpy_scene, create=True)
    albedo = None
    if per_albedo is not None:
        albedo_img = _ensure_image(albedo_image_name(name), per_albedo, per_albedo_filepath)
        # The pass first: the Render Layers node has no Diffuse Color output to link before.
        vl = _albedo_view_layer(tree, bpy_scene)
        _switch_diffuse_color(bpy_scene, vl.name)
        albedo = (albedo_img, bpy_scene, vl.name)
    _ensure_nodes(tree, img, albedo)
    if per_albedo is None:
        _switch_diffuse_color(bpy_scene, None)
        _remove_image(albedo_image_name(name))
    return img


def has_layer(bpy_scene, name="SMBS Caustics") -> bool:
    """Is there a caustic layer (our images, or our nodes in the scene's compositor)?"""
    tree, _ = _scene_tree(bpy_scene, create=False)
    return (_find_image(name) is not None or _find_image(albedo_image_name(name)) is not None
            or (tree is not None and bool(_ours(tree))))


def remove_layer(bpy_scene, name="SMBS Caustics"):
    """Take our nodes (or our whole node group) and images out again, and the Diffuse Color
    pass off if we switched it on."""
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
    _switch_diffuse_color(bpy_scene, None)
    _remove_image(name)
    _remove_image(albedo_image_name(name))


# ---------------------------------------------------------------------------
# Frame ranges: the layer as an image sequence


def _sequence_nodes(bpy_scene, first, last):
    """Our Image nodes (the layer's and the per-albedo one) play frames first..last: frame f of the scene
    reads the file of frame f (the files are numbered by the scene's frames)."""
    tree, _ = _scene_tree(bpy_scene, create=False)
    for node in (_ours(tree, IMAGE) + _ours(tree, ALBEDO_IMAGE)) if tree is not None else ():
        node.frame_start, node.frame_duration, node.frame_offset = first, last - first + 1, first - 1
        node.use_cyclic, node.use_auto_refresh = False, True


def _as_sequence(img, pattern, first, last):
    img.source = 'SEQUENCE'
    img.filepath = fill_frame(pattern, first)
    img[SEQUENCE] = {"pattern": str(pattern), "first": int(first), "last": int(last)}
    img.reload()


def apply_sequence(bpy_scene, image, pattern, frames, name="SMBS Caustics", per_albedo=None, albedo_pattern=None):
    """The layer of a frame range in the compositor: as apply_layer, from the EXRs ``pattern`` names (a run
    of # for the frame, Blender's convention) for frames (first, last), each frame of a render
    compositing its own. image, per_albedo: one frame's (for the size and whether the per-albedo part is
    there). Returns the Image datablock."""
    first, last = int(frames[0]), int(frames[1])
    img = apply_layer(bpy_scene, image, name, filepath=fill_frame(pattern, first), per_albedo=per_albedo,
                      per_albedo_filepath=fill_frame(albedo_pattern, first) if albedo_pattern else None)
    _as_sequence(img, pattern, first, last)
    if per_albedo is not None and albedo_pattern:
        _as_sequence(_find_image(albedo_image_name(name)), albedo_pattern, first, last)
    _sequence_nodes(bpy_scene, first, last)
    return img


def layer_sequence(name="SMBS Caustics"):
    """(pattern, first, last) of our layer where it is an image sequence of a frame range, else None."""
    img = _find_image(name)
    if img is None or img.source != 'SEQUENCE' or not img.get(SEQUENCE):
        return None
    seq = img[SEQUENCE]
    return str(seq["pattern"]), int(seq["first"]), int(seq["last"])
