"""The extension registers and unregisters cleanly; the caustic layer goes into the
compositor once, beside the user's own nodes, and comes out again; the operator bakes."""
import importlib
import json
import math

import numpy as np
import pytest

from conftest import load_extension

bpy = pytest.importorskip("bpy")

# Operators and panels show up in bpy.types; property groups do not.
TYPES = ("SMBS_OT_bake_caustics", "SMBS_PT_caustics", "SMBS_PT_caustics_advanced",
         "SMBS_PT_caustics_statistics")
LAYER = "SMBS Caustics"


def _handlers():
    return {name: list(getattr(bpy.app.handlers, name)) for name in dir(bpy.app.handlers)
            if isinstance(getattr(bpy.app.handlers, name), list)}


def _operator_registered():
    return "bake_caustics" in dir(bpy.ops.smbs)


def _classes(extension):
    return (*extension.ui.properties.classes, *extension.operators.classes,
            *extension.ui.panels.classes)


def _assert_registered(extension):
    assert all(cls.is_registered for cls in _classes(extension))
    for name in TYPES:
        assert hasattr(bpy.types, name), name
    assert "smbs_caustics" in bpy.types.Scene.bl_rna.properties
    assert _operator_registered()
    assert bpy.context.scene.smbs_caustics.method == "smbs"


def _assert_unregistered(extension, handlers_before):
    assert not any(cls.is_registered for cls in _classes(extension))
    for name in TYPES:
        assert not hasattr(bpy.types, name), f"{name} still registered"
    assert not hasattr(bpy.types.Scene, "smbs_caustics")
    assert "smbs_caustics" not in bpy.types.Scene.bl_rna.properties
    assert not hasattr(bpy.context.scene, "smbs_caustics")
    assert not _operator_registered()
    assert _handlers() == handlers_before


def test_register_unregister_leaves_nothing(empty_bpy):
    extension = load_extension()
    handlers = _handlers()
    assert not hasattr(bpy.types, "SMBS_OT_bake_caustics")
    for _ in range(2):  # a second round proves unregister really cleaned up
        extension.register()
        try:
            _assert_registered(extension)
        finally:
            extension.unregister()
        _assert_unregistered(extension, handlers)


def test_settings_defaults(empty_bpy, addon):
    s = bpy.context.scene.smbs_caustics
    assert (s.method, s.estimator, s.spp, s.output_path) == ("smbs", "unbiased", 16, "//caustics.exr")
    assert (s.max_iterations, s.max_chain, s.use_cycles_flags) == (20, 4, "AUTO")
    assert s.solver_threshold == pytest.approx(1e-5)
    assert s.tau == pytest.approx(0.85)
    assert s.large_mutation_tir and s.large_mutation_backlit and s.large_mutation_slow
    assert s.time_budget == 0.0 and s.last_stats == ""
    assert bpy.types.SMBS_PT_caustics.bl_context == "render"
    assert bpy.ops.smbs.bake_caustics.poll()


def test_statistics_summary(addon):
    panels = importlib.import_module("smbs_caustics.ui.panels")
    stats = {"time_s": 75.0, "rays": 122_000_000, "walks_succeeded": 55, "walks_started": 100,
             "mutations_per_path": 3.25,
             "lights": {"Key": {"time_s": 1.5, "rays_photon": 1000, "rays_camera": 500}},
             "skipped": [{"kind": "light", "name": "Fill", "reason": "no casters"}]}
    rows = dict(panels.summarize_stats(panels.parse_stats(json.dumps(stats))))
    assert rows == {"Success Rate": "55.0%", "Mutations per Path": "3.2", "Rays": "122.0 M",
                    "Time": "1 min 15 s"}
    assert panels.per_light_stats(stats) == [("Key", [("Rays", "1.5 k"), ("Time", "1.50 s")])]
    assert panels.skipped_stats(stats) == ["light Fill: no casters"]
    assert panels.parse_stats("not json") == {}


class _Layout:
    """Stands in for UILayout when calling a panel's draw(): checks every prop() and operator()."""

    def __init__(self, drawn):
        self.drawn = drawn

    def _sub(self, *args, **kwargs):
        return _Layout(self.drawn)

    column = row = split = box = _sub

    def prop(self, data, name, **kwargs):
        assert name in data.bl_rna.properties, f"no property {name!r}"
        self.drawn.append(name)

    def operator(self, idname, **kwargs):
        module, name = idname.split(".")
        assert name in dir(getattr(bpy.ops, module)), f"no operator {idname!r}"
        self.drawn.append(idname)

    def label(self, text="", **kwargs):
        self.drawn.append(text)


@pytest.mark.parametrize("last_stats", ["", '{"time_s": 2.0, "lights": {"Key": {"rays": 10}}}'])
def test_panels_draw(empty_bpy, addon, last_stats):
    from types import SimpleNamespace

    scene = bpy.context.scene
    scene.smbs_caustics.last_stats = last_stats
    context = SimpleNamespace(scene=scene)
    drawn = []
    for panel in addon.ui.panels.classes:
        panel.draw(SimpleNamespace(layout=_Layout(drawn)), context)
    assert {"method", "spp", "output_path", "smbs.bake_caustics", "tau", "max_chain"} <= set(drawn)
    assert ("No bake yet" in drawn) == (not last_stats)
    if last_stats:
        assert {"Time", "2.00 s", "Key", "Rays"} <= set(drawn)


# ---------------------------------------------------------------------------- compositor


@pytest.fixture
def composite(empty_bpy):
    return importlib.import_module(load_extension().__name__ + ".smbs_addon.composite")


def _layer(h=4, w=6, value=1.0):
    img = np.zeros((h, w, 3), np.float32)
    img[0] = (value, 0.0, 0.0)  # top row red
    img[-1] = (0.0, 0.0, value)  # bottom row blue
    return img


def _pixels(image):
    w, h = image.size
    buf = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(buf)
    return buf.reshape(h, w, 4)


def _our_nodes(tree, role):
    return [n for n in tree.nodes if n.get("smbs_caustics") == role]


def _layer_images():
    return [im for im in bpy.data.images if im.name.startswith(LAYER)]


def _source(socket):
    assert socket.is_linked, f"{socket.node.name}.{socket.name} is not linked"
    return socket.links[0].from_node


def test_apply_layer_twice_makes_one_image_and_one_group(composite):
    scene = bpy.context.scene
    assert scene.compositing_node_group is None
    composite.apply_layer(scene, _layer(value=1.0))
    img = composite.apply_layer(scene, _layer(value=2.0))

    assert [im.name for im in _layer_images()] == [LAYER] and img.name == LAYER
    assert img.is_float and img.colorspace_settings.name == "Linear Rec.709"
    px = _pixels(img)  # Blender's rows run bottom to top
    assert np.allclose(px[0, :, :3], (0, 0, 2)) and np.allclose(px[-1, :, :3], (2, 0, 0))
    assert np.all(px[..., 3] == 1.0)

    tree = scene.compositing_node_group
    assert tree is not None and len(bpy.data.node_groups) == 1
    (add,), (image_node,), (rl,) = (_our_nodes(tree, r) for r in ("add", "image", "render_layers"))
    assert image_node.image == img
    (out,) = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    assert _source(out.inputs[0]) == add
    a, b, _ = composite._add_sockets(add)
    assert _source(a) == rl and _source(b) == image_node

    composite.remove_layer(scene)
    assert scene.compositing_node_group is None
    assert len(bpy.data.node_groups) == 0 and not _layer_images()


def test_apply_layer_joins_the_users_compositor(composite):
    scene = bpy.context.scene
    tree = bpy.data.node_groups.new("Mine", "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    rl = tree.nodes.new("CompositorNodeRLayers")
    blur = tree.nodes.new("CompositorNodeBlur")
    out = tree.nodes.new("NodeGroupOutput")
    tree.links.new(rl.outputs["Image"], blur.inputs["Image"])
    tree.links.new(blur.outputs["Image"], out.inputs[0])
    scene.compositing_node_group = tree
    mine = {n.name for n in tree.nodes}

    composite.apply_layer(scene, _layer())
    composite.apply_layer(scene, _layer(value=3.0))

    assert scene.compositing_node_group == tree and len(bpy.data.node_groups) == 1
    assert len(_layer_images()) == 1
    (add,), (image_node,) = _our_nodes(tree, "add"), _our_nodes(tree, "image")
    assert not _our_nodes(tree, "render_layers")
    assert {n.name for n in tree.nodes} == mine | {add.name, image_node.name}
    assert _source(blur.inputs["Image"]) == rl  # the user's link is untouched
    assert _source(out.inputs[0]) == add
    a, b, _ = composite._add_sockets(add)
    assert _source(a) == blur and _source(b) == image_node
    assert np.allclose(_pixels(image_node.image)[-1, :, :3], (3, 0, 0))

    composite.remove_layer(scene)
    assert scene.compositing_node_group == tree
    assert {n.name for n in tree.nodes} == mine
    assert _source(out.inputs[0]) == blur and _source(blur.inputs["Image"]) == rl
    assert not _layer_images()


def test_apply_layer_feeds_an_unlinked_output_from_render_layers(composite):
    scene = bpy.context.scene
    tree = bpy.data.node_groups.new("Bare", "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    out = tree.nodes.new("NodeGroupOutput")
    scene.compositing_node_group = tree
    composite.apply_layer(scene, _layer())
    (add,), (rl,) = _our_nodes(tree, "add"), _our_nodes(tree, "render_layers")
    assert _source(out.inputs[0]) == add and _source(composite._add_sockets(add)[0]) == rl
    composite.remove_layer(scene)
    assert [n.name for n in tree.nodes] == [out.name] and not out.inputs[0].is_linked


def test_apply_layer_reads_the_written_exr(composite, tmp_path):
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.imageio")
    path = tmp_path / "caustics.exr"
    layer = _layer(value=5.0)
    imageio.write_exr(path, layer, {"method": "test"})
    img = composite.apply_layer(bpy.context.scene, layer, filepath=str(path))
    assert img.source == 'FILE' and bpy.path.abspath(img.filepath) == str(path)
    assert not img.packed_file
    assert np.allclose(_pixels(img)[::-1, :, :3], layer)
    # Without a file the next bake is packed into the same datablock name.
    img = composite.apply_layer(bpy.context.scene, _layer(value=1.0))
    assert [im.name for im in _layer_images()] == [LAYER] and img.packed_file


def test_cycles_render_shows_the_layer(composite, tmp_path):
    """The compositor really adds the layer to a render, the right way up."""
    scene = bpy.context.scene  # no world, no objects: the render itself is black
    scene.render.engine = 'CYCLES'
    scene.cycles.samples = 1
    scene.render.resolution_x, scene.render.resolution_y = 32, 16
    scene.render.resolution_percentage = 100
    scene.camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(scene.camera)
    layer = np.zeros((16, 32, 3), np.float32)
    layer[:, :16, 1] = 0.5  # left half green
    layer[:4, :, 0] = 2.0  # top rows red
    composite.apply_layer(scene, layer)
    scene.render.image_settings.file_format = 'OPEN_EXR'
    scene.render.image_settings.color_depth = '32'
    scene.render.filepath = str(tmp_path / "render.exr")
    bpy.ops.render.render(write_still=True)
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.imageio")
    rendered, _ = imageio.read_exr(tmp_path / "render.exr")
    assert np.allclose(rendered[..., :3], layer, atol=1e-4)


# ---------------------------------------------------------------------------- the operator


def test_output_path_resolution(empty_bpy, addon, tmp_path, monkeypatch):
    bake_op = importlib.import_module(addon.__name__ + ".operators.bake")
    monkeypatch.chdir(tmp_path)
    # Unsaved blend file, background mode: relative paths land in the working directory.
    path, stored, note = bake_op.resolve_output_path("//caustics.exr")
    assert path == stored == str(tmp_path / "caustics.exr") and note
    path, _, _ = bake_op.resolve_output_path("//layers/")
    assert path == str(tmp_path / "layers" / "caustics.exr")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "shot.blend"))
    path, stored, note = bake_op.resolve_output_path("//caustics")
    assert (path, stored, note) == (str(tmp_path / "caustics.exr"), "//caustics.exr", None)



def _mirror_scene(width=24, height=16):
    """A disk light, a mirror tilted 45 degrees, a floor: a bright reflected spot."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100

    def material(name, node_type, color):
        mat = bpy.data.materials.new(name)
        nodes = mat.node_tree.nodes
        nodes.clear()
        bsdf, out = nodes.new(node_type), nodes.new("ShaderNodeOutputMaterial")
        bsdf.inputs["Color"].default_value = (*color, 1.0)
        mat.node_tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
        return mat

    def plane(name, size, mat, location, rotation):
        s = size / 2
        me = bpy.data.meshes.new(name)
        me.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
        me.materials.append(mat)
        ob = bpy.data.objects.new(name, me)
        ob.location, ob.rotation_euler = location, rotation
        scene.collection.objects.link(ob)

    plane("Floor", 10, material("Floor", "ShaderNodeBsdfDiffuse", (0.8,) * 3), (0, 0, 0), (0, 0, 0))
    plane("Mirror", 1.5, material("Mirror", "ShaderNodeBsdfGlossy", (0.9,) * 3),
          (0, 0, 1.5), (0, math.radians(-135), 0))
    light = bpy.data.lights.new("Disk", 'AREA')
    light.shape, light.size, light.energy = 'DISK', 0.5, 100.0
    ob = bpy.data.objects.new("Disk", light)
    ob.location, ob.rotation_euler = (-2, 0, 1.5), (0, math.radians(-90), 0)
    scene.collection.objects.link(ob)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0, -6, 5), (math.radians(50), 0, 0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def test_bake_operator_end_to_end(empty_bpy, addon, tmp_path):
    try:
        importlib.import_module(addon.__name__ + ".smbs_addon.bake")
        importlib.import_module(addon.__name__ + ".smbs_addon.export")
    except ImportError as e:
        pytest.skip(f"the render core cannot be imported yet: {e}")
    scene = _mirror_scene()
    settings = scene.smbs_caustics
    settings.method, settings.spp, settings.seed = "reference", 1, 3
    settings.output_path = str(tmp_path / "layer.exr")

    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert (tmp_path / "layer.exr").is_file()
    stats = json.loads(settings.last_stats)
    assert stats and "Disk" in stats.get("lights", {"Disk": 1})
    img = bpy.data.images[LAYER]
    assert img.size[:] == (24, 16) and img.source == 'FILE' and not img.packed_file
    assert _pixels(img)[..., :3].max() > 0.0, "the mirror should throw a caustic on the floor"
    assert _our_nodes(scene.compositing_node_group, "image")[0].image == img

    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}  # a re-bake reuses everything
    assert len(_layer_images()) == 1 and len(bpy.data.node_groups) == 1


def test_bake_operator_reports_scene_errors(empty_bpy, addon, tmp_path):
    try:
        importlib.import_module(addon.__name__ + ".smbs_addon.export")
    except ImportError as e:
        pytest.skip(f"the render core cannot be imported yet: {e}")
    bpy.context.scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    with pytest.raises(RuntimeError, match="no camera"):  # ERROR reports raise in bpy.ops calls
        bpy.ops.smbs.bake_caustics()
    assert not (tmp_path / "layer.exr").exists()
