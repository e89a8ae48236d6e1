"""Textured receivers in the compositor: the bake's per-albedo image times the render's own
Diffuse Color pass is added beside the caustic layer, updated in place, and taken out again
with the user's compositor and view layer passes as they were."""
import importlib
import json
import time

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from testkit.addon import ALBEDO, LAYER, image_pixels, layer_image, our_nodes, users_compositor  # noqa: E402
from testkit.blend import mirror_scene, node_material, plane  # noqa: E402
from testkit.extension import load_extension  # noqa: E402

ALBEDO_ROLES = ("albedo_image", "diffuse_color", "multiply", "albedo_add")


def _per_albedo(h=4, w=6, value=0.2):
    img = np.full((h, w, 3), value, np.float32)
    img[0] = (0.0, value, 0.0)  # top row green
    return img


def _one(tree, role):
    (node,) = our_nodes(tree, role)
    return node


def _images():
    return sorted(im.name for im in bpy.data.images if im.name.startswith(LAYER))


def _link(socket):
    assert socket.is_linked, f"{socket.node.name}.{socket.name} is not linked"
    return socket.links[0].from_socket


def _links(tree):
    return {(ln.from_node.name, ln.from_socket.identifier, ln.to_node.name, ln.to_socket.identifier)
            for ln in tree.links}


def _users_tree(scene):
    """The user's compositor: Render Layers -> Blur -> Group Output."""
    return users_compositor(scene)[0]


def _assert_albedo_chain(composite, tree, scene, view_layer="ViewLayer"):
    """image + per-albedo image x Diffuse Color feeds our Add's second input; returns the nodes."""
    add, image_node = _one(tree, "add"), _one(tree, "image")
    albedo_node, rl, mul, total = (_one(tree, role) for role in ALBEDO_ROLES)
    assert albedo_node.image == bpy.data.images[ALBEDO] and image_node.image == bpy.data.images[LAYER]
    assert rl.bl_idname == "CompositorNodeRLayers" and rl.scene == scene and rl.layer == view_layer
    assert (mul.data_type, mul.blend_type, mul.clamp_result) == ('RGBA', 'MULTIPLY', False)
    assert (total.data_type, total.blend_type, total.clamp_result) == ('RGBA', 'ADD', False)
    assert mul.inputs["Factor"].default_value == 1.0 and total.inputs["Factor"].default_value == 1.0
    mul_a, mul_b, mul_result = composite._add_sockets(mul)
    sum_a, sum_b, sum_result = composite._add_sockets(total)
    assert _link(mul_a).node == albedo_node
    assert _link(mul_b).node == rl and _link(mul_b).identifier == "Diffuse Color"
    assert _link(mul_b).enabled
    assert _link(sum_a).node == image_node and _link(sum_b) == mul_result
    assert _link(composite._add_sockets(add)[1]) == sum_result
    return add, image_node, albedo_node, rl, mul, total


def test_per_albedo_is_multiplied_by_the_diffuse_color_pass(composite):
    scene = bpy.context.scene
    vl = scene.view_layers[0]
    assert not vl.use_pass_diffuse_color
    img = composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())

    assert img.name == LAYER and _images() == [LAYER, ALBEDO]
    albedo = bpy.data.images[ALBEDO]
    assert albedo.get("smbs_caustics") == ALBEDO and albedo.is_float and albedo.packed_file
    assert albedo.colorspace_settings.name == "Linear Rec.709"
    px = image_pixels(albedo)  # Blender's rows run bottom to top
    assert np.allclose(px[-1, :, :3], (0, 0.2, 0)) and np.allclose(px[0, :, :3], 0.2)

    tree = scene.compositing_node_group
    add, *_ = _assert_albedo_chain(composite, tree, scene)
    (out,) = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    assert _link(out.inputs[0]).node == add  # the sum reaches the output
    assert _link(composite._add_sockets(add)[0]).node == _one(tree, "render_layers")
    assert vl.use_pass_diffuse_color
    assert composite.diffuse_color_switched_on(scene) == vl.name
    assert composite.has_layer(scene)

    composite.remove_layer(scene)  # our own node group goes as a whole
    assert scene.compositing_node_group is None and len(bpy.data.node_groups) == 0
    assert _images() == [] and not vl.use_pass_diffuse_color
    assert composite.diffuse_color_switched_on(scene) is None and not composite.has_layer(scene)


def test_per_albedo_updates_in_place_and_goes_again(composite, tmp_path):
    scene = bpy.context.scene
    tree = _users_tree(scene)
    mine, links = {n.name for n in tree.nodes}, _links(tree)
    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    nodes = {n.name for n in tree.nodes}
    assert len(nodes) == len(mine) + 6

    # Again, from the written EXRs this time: the same nodes, one image of each, new pixels.
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.io.exr")
    path, albedo_path = tmp_path / "caustics.exr", tmp_path / "caustics_per_albedo.exr"
    imageio.write_exr(path, layer_image(value=3.0))
    imageio.write_exr(albedo_path, _per_albedo(value=0.7))
    composite.apply_layer(scene, layer_image(value=3.0), filepath=str(path), per_albedo=_per_albedo(value=0.7),
                          per_albedo_filepath=str(albedo_path))
    assert {n.name for n in tree.nodes} == nodes and _images() == [LAYER, ALBEDO]
    _assert_albedo_chain(composite, tree, scene)
    albedo = bpy.data.images[ALBEDO]
    assert albedo.source == 'FILE' and not albedo.packed_file
    assert bpy.path.abspath(albedo.filepath) == str(albedo_path)
    assert np.allclose(image_pixels(albedo)[::-1, :, :3], _per_albedo(value=0.7))
    assert scene.view_layers[0].use_pass_diffuse_color

    # Without per_albedo: the per-albedo nodes and image go, the pass is off again.
    composite.apply_layer(scene, layer_image())
    add, image_node = _one(tree, "add"), _one(tree, "image")
    assert {n.name for n in tree.nodes} == mine | {add.name, image_node.name}
    assert _link(composite._add_sockets(add)[1]).node == image_node
    assert _images() == [LAYER] and not scene.view_layers[0].use_pass_diffuse_color
    assert composite.diffuse_color_switched_on(scene) is None

    # Back again, then a user deleting one of our nodes: rebuilt, never duplicated.
    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    tree.nodes.remove(_one(tree, "multiply"))
    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    assert len(tree.nodes) == len(nodes) and _images() == [LAYER, ALBEDO]
    _assert_albedo_chain(composite, tree, scene)

    composite.remove_layer(scene)
    assert {n.name for n in tree.nodes} == mine and _links(tree) == links
    assert _images() == [] and not scene.view_layers[0].use_pass_diffuse_color


def test_remove_layer_switches_off_only_the_pass_it_switched_on(composite):
    scene = bpy.context.scene
    first = scene.view_layers[0]
    first.use_pass_diffuse_color = True  # the user's
    tree = _users_tree(scene)
    mine, links = {n.name for n in tree.nodes}, _links(tree)

    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    assert composite.diffuse_color_switched_on(scene) is None  # it was on already
    _assert_albedo_chain(composite, tree, scene)
    composite.remove_layer(scene)
    assert {n.name for n in tree.nodes} == mine and _links(tree) == links
    assert first.use_pass_diffuse_color  # the user's pass stays on
    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    composite.apply_layer(scene, layer_image())
    assert first.use_pass_diffuse_color

    # The first view layer not rendered: the one that is; our pass goes off with the layer.
    composite.remove_layer(scene)
    first.use = False
    second = scene.view_layers.new("Second")
    composite.apply_layer(scene, layer_image(), per_albedo=_per_albedo())
    _assert_albedo_chain(composite, tree, scene, view_layer="Second")
    assert second.use_pass_diffuse_color and composite.diffuse_color_switched_on(scene) == "Second"
    composite.remove_layer(scene)
    assert not second.use_pass_diffuse_color and first.use_pass_diffuse_color
    assert {n.name for n in tree.nodes} == mine and _links(tree) == links
    assert _images() == [] and composite.diffuse_color_switched_on(scene) is None


def test_cycles_render_adds_per_albedo_times_diffuse_color(composite, tmp_path):
    """render + layer + per_albedo x Diffuse Color, pixel by pixel: a flat diffuse plane of
    colour 0.5 under a grey sky, seen from above by an orthographic camera."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.samples, scene.cycles.use_denoising = 4, False
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    scene.world = bpy.data.worlds.new("Sky")
    scene.world.color = (0.3, 0.3, 0.3)
    background = scene.world.node_tree and scene.world.node_tree.nodes.get("Background")
    if background:
        background.inputs["Color"].default_value = (0.3, 0.3, 0.3, 1.0)
    plane(scene, "Floor", 10, node_material("Floor", "ShaderNodeBsdfDiffuse", (0.5,) * 3), (0, 0, 0))
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.type, cam.data.ortho_scale, cam.location = 'ORTHO', 2.0, (0, 0, 3)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.io.exr")

    def render(name, compositing):
        scene.render.use_compositing = compositing
        scene.render.filepath = str(tmp_path / name)
        bpy.ops.render.render(write_still=True)
        return imageio.read_exr(tmp_path / name)[0][..., :3]

    plain = render("plain.exr", False)  # the same seed: the same render
    assert plain.min() > 0.05
    layer, per_albedo = layer_image(8, 8), _per_albedo(8, 8)
    composite.apply_layer(scene, layer, per_albedo=per_albedo)
    composited = render("composited.exr", True)
    assert np.allclose(composited, plain + layer + per_albedo * 0.5, atol=1e-5)
    assert np.allclose((composited - plain - layer)[3], 0.1, atol=1e-5)


# ---------------------------------------------------------------------------- the operator


def test_finish_writes_and_composites_the_per_albedo_image(empty_bpy, addon, tmp_path):
    """finish(): the EXR holds result.layer(), a sidecar EXR the per-albedo image, both read by
    their Image datablocks; the switched-on pass is reported once; a result without a per-albedo
    part takes it out again."""
    bake_op = importlib.import_module(addon.__name__ + ".operators.bake")
    core_bake = importlib.import_module(addon.__name__ + ".smbs_addon.baking.result")
    imageio = importlib.import_module(addon.__name__ + ".smbs_addon.io.exr")
    scene = mirror_scene(6, 4)
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    core = bake_op._core()
    prep = bake_op.prepare(bpy.context, core)
    stats = {"time_s": 1.0, "rays": 10, "noise": {"relative_noise": 0.1}}
    image, textured = layer_image(value=2.0), layer_image(value=0.5)
    result = core_bake.BakeResult(image=image, variance=np.zeros_like(image), stats=stats,
                                  textured=textured, per_albedo=_per_albedo())
    reports = []

    def report(levels, text):
        reports.append((set(levels), text))

    assert bake_op.finish(scene, prep, result, core, report)
    assert not [r for r in reports if 'ERROR' in r[0]], reports
    colour = imageio.read_exr(tmp_path / "layer.exr")[0]
    assert np.allclose(colour[..., :3], image - textured)
    assert np.allclose(imageio.read_exr(tmp_path / "layer_per_albedo.exr")[0][..., :3], _per_albedo())
    img, albedo = bpy.data.images[LAYER], bpy.data.images[ALBEDO]
    assert img.source == albedo.source == 'FILE' and not albedo.packed_file
    # Blender reads the colour of the EXR, not its extra channels (std, per_albedo_R, ...)
    assert np.allclose(image_pixels(img)[::-1, :, :3], image - textured)
    assert np.allclose(image_pixels(albedo)[::-1, :, :3], _per_albedo())
    assert bpy.path.abspath(albedo.filepath) == str(tmp_path / "layer_per_albedo.exr")
    _assert_albedo_chain(importlib.import_module(addon.__name__ + ".smbs_addon.blender.composite"),
                         scene.compositing_node_group, scene)
    switched = [text for levels, text in reports if levels == {'INFO'} and "Diffuse Color pass" in text]
    assert len(switched) == 1 and "'ViewLayer'" in switched[0], reports
    assert scene.view_layers[0].use_pass_diffuse_color

    reports.clear()
    assert bake_op.finish(scene, prep, result, core, report)  # a re-bake: nothing new to say
    assert not [text for _, text in reports if "Diffuse Color pass" in text]
    assert _images() == [LAYER, ALBEDO]

    plain = core_bake.BakeResult(image=image, variance=np.zeros_like(image), stats=stats)
    prep.started = time.perf_counter()
    assert bake_op.finish(scene, prep, plain, core, report)
    assert np.allclose(imageio.read_exr(tmp_path / "layer.exr")[0][..., :3], image)
    assert _images() == [LAYER] and not scene.view_layers[0].use_pass_diffuse_color
    assert not any(our_nodes(scene.compositing_node_group, role) for role in ALBEDO_ROLES)


def test_the_operator_bakes_a_textured_floor_into_the_compositor(empty_bpy, addon, tmp_path):
    """Bake Caustics on the mirror scene whose floor's colour is a Checker Texture: the layer EXR,
    its per-albedo EXR beside it, both images in the compositor with the Diffuse Color pass
    switched on, and the panel's statistics say the share; Remove Caustic Layer takes it all out."""
    scene = mirror_scene(24, 16)
    floor = bpy.data.materials["Floor"]
    nt = floor.node_tree
    tex = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(tex.outputs["Color"], nt.nodes["Diffuse BSDF"].inputs["Color"])
    s = scene.smbs_caustics
    s.method, s.spp, s.batches, s.seed = "reference", 4, 2, 1
    s.output_path = str(tmp_path / "layer.exr")
    vl = scene.view_layers[0]
    assert not vl.use_pass_diffuse_color
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert (tmp_path / "layer.exr").is_file() and (tmp_path / "layer_per_albedo.exr").is_file()
    assert vl.use_pass_diffuse_color
    assert bpy.data.images.get(ALBEDO) is not None
    stats = json.loads(s.last_stats)
    assert 0.9 < stats["textured_share"] <= 1.0 + 1e-6  # the floor is seen directly everywhere
    tree = scene.compositing_node_group
    assert len(our_nodes(tree, "multiply")) == 1 and len(our_nodes(tree, "albedo_image")) == 1
    assert bpy.ops.smbs.remove_caustic_layer() == {'FINISHED'}
    assert not vl.use_pass_diffuse_color and bpy.data.images.get(ALBEDO) is None
