"""The extension registers and unregisters cleanly; the caustic layer goes into the
compositor once, beside the user's own nodes, and comes out again; the operator bakes."""
import importlib
import json
import math

import numpy as np
import pytest

from testkit.extension import load_extension

bpy = pytest.importorskip("bpy")

from testkit.addon import (LAYER, Layout, draw_all, image_pixels, layer_image, layer_images,  # noqa: E402
                           our_nodes, users_compositor)
from testkit.blend import mirror_scene, node_material, plane  # noqa: E402

# Operators and panels show up in bpy.types; property groups do not.
TYPES = ("SMBS_OT_bake_caustics", "SMBS_OT_cancel_bake", "SMBS_OT_remove_caustic_layer",
         "SMBS_PT_caustics", "SMBS_UL_participants", "SMBS_PT_caustics_participants",
         "SMBS_PT_caustics_advanced", "SMBS_PT_caustics_statistics")
OPERATORS = ("bake_caustics", "cancel_bake", "remove_caustic_layer", "show_plan")


def _handlers():
    return {name: list(getattr(bpy.app.handlers, name)) for name in dir(bpy.app.handlers)
            if isinstance(getattr(bpy.app.handlers, name), list)}


def _operators_registered():
    return [name for name in OPERATORS if name in dir(bpy.ops.smbs)]


def _classes(extension):
    return (*extension.ui.properties.classes, *extension.operators.classes,
            *extension.ui.panels.classes)


def _assert_registered(extension):
    assert all(cls.is_registered for cls in _classes(extension))
    for name in TYPES:
        assert hasattr(bpy.types, name), name
    assert "smbs_caustics" in bpy.types.Scene.bl_rna.properties
    assert _operators_registered() == list(OPERATORS)
    assert bpy.context.scene.smbs_caustics.method == "auto"
    assert extension.operators.cli.registered()


def _assert_unregistered(extension, handlers_before):
    assert not any(cls.is_registered for cls in _classes(extension))
    for name in TYPES:
        assert not hasattr(bpy.types, name), f"{name} still registered"
    assert not hasattr(bpy.types.Scene, "smbs_caustics")
    assert "smbs_caustics" not in bpy.types.Scene.bl_rna.properties
    assert not hasattr(bpy.context.scene, "smbs_caustics")
    assert not _operators_registered()
    assert _handlers() == handlers_before
    assert not extension.operators.cli.registered()
    assert not extension.operators.bake._running


def _timers_of(extension):
    """Functions of the extension's modules registered as bpy.app.timers (there should be none)."""
    modules = (extension.operators.bake, extension.operators.cli, extension.operators.job,
               extension.operators.policy, extension.ui.panels, extension.ui.properties)
    return [f"{m.__name__}.{name}" for m in modules for name, fn in vars(m).items()
            if callable(fn) and not isinstance(fn, type) and bpy.app.timers.is_registered(fn)]


def _cli_command_free(capfd):
    """True if the id 'smbs_bake' is free: registering it again prints no duplicate warning."""
    capfd.readouterr()
    handle = bpy.utils.register_cli_command("smbs_bake", lambda argv: 0)
    bpy.utils.unregister_cli_command(handle)
    out, err = capfd.readouterr()
    return "duplicate" not in out + err


def test_register_unregister_leaves_nothing(empty_bpy, tmp_path, capfd):
    """Register, bake, unregister, re-register, twice: nothing is left behind."""
    extension = load_extension()
    assert not hasattr(bpy.types, "SMBS_OT_bake_caustics")
    assert _cli_command_free(capfd)
    for round_ in range(2):  # a second round proves unregister really cleaned up
        bpy.ops.wm.read_factory_settings(use_empty=True)  # (adds Blender's own handlers)
        handlers = _handlers()
        extension.register()
        try:
            _assert_registered(extension)
            assert not _cli_command_free(capfd), "smbs_bake is not registered"
            scene = mirror_scene(12, 8)
            s = scene.smbs_caustics
            s.method, s.spp, s.batches = "reference", 1, 2
            s.output_path = str(tmp_path / f"layer{round_}.exr")
            assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
            assert _timers_of(extension) == []
        finally:
            extension.unregister()
        _assert_unregistered(extension, handlers)
        assert _cli_command_free(capfd), "smbs_bake still registered"
        assert _timers_of(extension) == []


def test_ui_settings_are_the_core_settings(empty_bpy, addon):
    """Every bake setting in the panel is a BakeSettings field of the same name, with the same
    default as the core (and so as the command line), once float32 storage is undone."""
    import dataclasses

    bake_op = importlib.import_module(addon.__name__ + ".operators.bake")
    core = importlib.import_module(addon.__name__ + ".smbs_addon.baking.bake")
    fields = {f.name: f.default for f in dataclasses.fields(core.BakeSettings)}
    props = bpy.context.scene.smbs_caustics
    names = addon.ui.properties.BAKE_FIELDS
    assert set(names) <= set(fields), set(names) - set(fields)
    # the core fields without a UI setting: the explicit chain list (empty: from the scene), the frame
    # (Bake Frame Range sets it to each frame's), the farm's shards (the command line's), and the anchored
    # estimator's share of samples that also walk at random (a research setting: 1, bench/results/pools.md)
    assert set(fields) - set(names) == {"chains", "frame", "shard", "shards", "anchor_walks"}
    settings, ignored = bake_op.bake_settings_from(props, core.BakeSettings)
    assert ignored == []
    assert settings == core.BakeSettings()
    props.solver_threshold, props.tau, props.spp, props.method = 3e-7, 0.9, 5, "mnee"
    props.anchor, props.seeding = False, "frame"
    settings, _ = bake_op.bake_settings_from(props, core.BakeSettings)
    assert (settings.solver_threshold, settings.tau, settings.spp, settings.method) == (3e-7, 0.9, 5, "mnee")
    assert (settings.anchor, settings.seeding) == (False, "frame")
    # Stop By: samples ignores the time limit and the noise target; time and noise bake in passes
    # of one sample per pixel per batch, noise with the time limit as a cap
    props.time_budget, props.noise_target = 30.0, 0.08
    settings, _ = bake_op.bake_settings_from(props, core.BakeSettings)
    assert (settings.time_budget, settings.noise_target, settings.spp) == (0.0, 0.0, 5)
    props.stop_rule = "TIME"
    settings, _ = bake_op.bake_settings_from(props, core.BakeSettings)
    assert (settings.time_budget, settings.noise_target, settings.spp) == (30.0, 0.0, settings.batches)
    props.stop_rule = "NOISE"
    settings, _ = bake_op.bake_settings_from(props, core.BakeSettings)
    assert (settings.time_budget, settings.noise_target) == (30.0, 0.08)


def test_settings_defaults(empty_bpy, addon):
    s = bpy.context.scene.smbs_caustics
    assert (s.method, s.estimator, s.spp, s.output_path) == ("auto", "unbiased", 16, "//caustics.exr")
    assert s.pilots == 4096 and s.plan_text == ""
    assert (s.max_iterations, s.max_chain, s.use_cycles_flags) == (20, 4, "AUTO")
    assert (s.trials, s.max_trials, s.batches, s.threads, s.guide) == (4, 10000, 8, 0, True)
    assert s.solver_threshold == pytest.approx(1e-6)
    assert s.tau == pytest.approx(0.85)
    assert s.large_mutation_tir and s.large_mutation_backlit and s.large_mutation_slow
    assert s.time_budget == 0.0 and s.last_stats == ""
    assert s.keep_out_of_cycles and not s.cycles_kept_out and s.cycles_note == ""
    assert bpy.types.SMBS_PT_caustics.bl_context == "render"
    assert bpy.ops.smbs.bake_caustics.poll()
    assert not bpy.ops.smbs.cancel_bake.poll()  # nothing is running


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
    textured = dict(panels.summarize_stats({**stats, "textured_share": 0.873}))
    assert textured["On Textures"] == "87% \u00d7 Diffuse Color"
    first = dict(panels.summarize_stats({**stats, "compile_s": 61.5}))  # the first bake after installing
    assert first["Of Which Compiling"] == "1 min 2 s (once)"
    assert "Of Which Compiling" not in dict(panels.summarize_stats({**stats, "compile_s": 0.0}))


def test_statistics_of_a_manifold_bake(addon):
    """The per-light statistics the core writes for SMBS (see smbs_addon.baking.bake) all reach the panel."""
    panels = importlib.import_module("smbs_caustics.ui.panels")
    light = {"time_s": 5.13, "walks": 65202, "successes": 21703, "success_rate": 0.3329,
             "mutations_per_path": 11.16, "mutations_per_success": 33.52, "large_mutations": {"tir": 0, "backlit": 3, "slow": 72753},
             "trials": {"mean": 1.00005, "max": 2, "capped": 0}, "rays": 898133,
             "rays_seed": 86907, "rays_walk": 789523}
    stats = {"method": "smbs", "resolution": [160, 120], "batches_done": 8, "time_s": 5.65,
             "rays": 1138192, "walks": 65202, "success_rate": 0.3329, "mutations_per_path": 11.16,
             "mutations_per_success": 33.52, "lights": {"Light": light}, "skipped": [],
             "noise": {"region_pixels": 4021, "relative_noise": 0.181, "mean": 0.51},
             "relative_error": 0.0734, "seconds_to_halve_error": 67.8, "stopped_by": "noise"}
    assert panels.bake_header(stats) == "SMBS, 160 x 120, 8 batches"
    assert dict(panels.summarize_stats(stats)) == {
        "Walks": "65.2 k", "Success Rate": "33.3%", "Mutations per Path": "11.2",
        "Mutations per Solution": "33.5", "Rays": "1.1 M",
        "Time": "5.65 s", "Relative Noise": "18.1%", "Error": "\u00b17.3% RMS",
        "Half the Error": "+1 min 8 s", "Stopped By": "Noise"}
    biased = {**stats, "error_leaves_out": ["MNEE's bias (one walk per point, no Bernoulli weights)",
                                            "the Bernoulli trials' cap (at least 0.2% of the layer)"]}
    assert dict(panels.summarize_stats(biased))["Not in the Error"] == "MNEE's bias; the Bernoulli trials' cap"
    ((name, rows),) = panels.per_light_stats(stats)
    assert name == "Light"
    assert dict(rows) == {"Walks": "65.2 k", "Success Rate": "33.3%", "Mutations per Path": "11.2",
                          "Mutations per Solution": "33.5",
                          "Large Mutations": "TIR 0, back-lit 3, slow 72.8 k",
                          "Bernoulli Trials": "mean 1.00, max 2, capped 0", "Rays": "898.1 k",
                          "Time": "5.13 s"}


def test_bent_normal_paths_are_counted_for_every_method(addon):
    """The paths through normals Cycles' Bump Map Correction bends: every method keeps them in its
    eye pass's "bent" part (the manifold methods' bakes before stop 33 kept them in the eye pass
    itself, and a scene's stored statistics may still hold those)."""
    panels = importlib.import_module("smbs_caustics.ui.panels")
    lt = {"eye_pass": {"eye_paths": 10, "bent": {"time_s": 0.5, "eye_paths": 4, "bent_paths": 1266}}}
    assert dict(panels.summarize_stats(lt))["Bent Normals"] == "1.3 k paths"
    assert dict(panels.summarize_stats({"eye_pass": {"bent_paths": 42}}))["Bent Normals"] == "42 paths"
    assert "Bent Normals" not in dict(panels.summarize_stats({"eye_pass": {"eye_paths": 10}}))


def test_capped_trials_show_what_they_leave_out(addon):
    panels = importlib.import_module("smbs_caustics.ui.panels")
    trials = {"mean": 2.36, "max": 8, "capped": 50, "capped_energy_min": 6.1, "capped_share_min": 0.104}
    assert dict(panels.summarize_stats({"trials": trials}))["Bernoulli Trials"] == (
        "mean 2.36, max 8, capped 50 (at least 10.4% of the layer missing)")
    trials.update(capped=0, capped_energy_min=0.0, capped_share_min=0.0)
    assert dict(panels.summarize_stats({"trials": trials}))["Bernoulli Trials"] == "mean 2.36, max 8, capped 0"


@pytest.mark.parametrize("last_stats", ["", '{"time_s": 2.0, "lights": {"Key": {"rays": 10}}}'])
def test_panels_draw(empty_bpy, addon, last_stats):
    scene = bpy.context.scene
    scene.smbs_caustics.last_stats = last_stats
    drawn = []
    draw_all(addon, scene, drawn)
    assert {"method", "estimator", "max_trials", "spp", "time_budget", "noise_target", "stop_rule", "seed",
            "use_cycles_flags",
            "keep_out_of_cycles", "output_path", "smbs.bake_caustics", "batches", "threads", "guide",
            "radiance",
            "max_iterations", "solver_threshold", "uniqueness", "tau", "max_chain",
            "large_mutation_tir", "large_mutation_backlit", "large_mutation_slow",
            "SMBS_UL_participants"} <= set(drawn)
    assert ("No bake yet" in drawn) == (not last_stats)
    if last_stats:
        assert {"Time", "2.00 s", "Key", "Rays"} <= set(drawn)
    scene.smbs_caustics.estimator = "biased"
    scene.smbs_caustics.cycles_note = "The layer holds ...\nCycles' own caustics are off"
    drawn = []
    draw_all(addon, scene, drawn)
    assert "trials" in drawn and "max_trials" not in drawn
    assert "The layer holds ..." in drawn and "Cycles' own caustics are off" in drawn


def test_participants_list_shows_cycles_flags(empty_bpy, addon):
    """The list holds the scene's renderable objects and lights, each with Cycles' own flags."""
    from types import SimpleNamespace

    scene = mirror_scene()
    hidden = bpy.data.objects.new("Hidden", bpy.data.meshes.new("Hidden"))
    hidden.hide_render = True
    scene.collection.objects.link(hidden)
    ul = bpy.types.SMBS_UL_participants
    fake = SimpleNamespace(bitflag_filter_item=1 << 30, filter_name="",  # UILST_FLT_ITEM
                           use_filter_sort_alpha=False)
    flags, order = ul.filter_items(fake, bpy.context, scene, "objects")
    shown = {ob.name for ob, f in zip(scene.objects, flags) if f}
    assert shown == {"Floor", "Mirror", "Disk"}
    for ob in (scene.objects[name] for name in shown):
        drawn = []
        ul.draw_item(None, bpy.context, Layout(drawn), scene, ob, 0, None, "", 0)
        expected = (["is_caustics_light"] if ob.type == 'LIGHT'
                    else ["is_caustics_caster", "is_caustics_receiver"])
        assert [d for d in drawn if d.startswith("is_caustics")] == expected
    # the world is a light of the layer too: its flag under the list, with its name
    panel = bpy.types.SMBS_PT_caustics_participants
    for world, rows in ((None, []), ("Sky", ["Sky", "is_caustics_light"])):
        scene.world = world and bpy.data.worlds.new(world)
        drawn = []
        panel.draw(SimpleNamespace(layout=Layout(drawn)), SimpleNamespace(scene=scene))
        assert [d for d in drawn if d in ("Sky", "is_caustics_light")] == rows


# ---------------------------------------------------------------------------- compositor


def _source(socket):
    assert socket.is_linked, f"{socket.node.name}.{socket.name} is not linked"
    return socket.links[0].from_node


def test_apply_layer_twice_makes_one_image_and_one_group(composite):
    scene = bpy.context.scene
    assert scene.compositing_node_group is None
    composite.apply_layer(scene, layer_image(value=1.0))
    img = composite.apply_layer(scene, layer_image(value=2.0))

    assert [im.name for im in layer_images()] == [LAYER] and img.name == LAYER
    assert img.is_float and img.colorspace_settings.name == "Linear Rec.709"
    px = image_pixels(img)  # Blender's rows run bottom to top
    assert np.allclose(px[0, :, :3], (0, 0, 2)) and np.allclose(px[-1, :, :3], (2, 0, 0))
    assert np.all(px[..., 3] == 1.0)

    tree = scene.compositing_node_group
    assert tree is not None and len(bpy.data.node_groups) == 1
    (add,), (image_node,), (rl,) = (our_nodes(tree, r) for r in ("add", "image", "render_layers"))
    assert image_node.image == img
    (out,) = [n for n in tree.nodes if n.bl_idname == "NodeGroupOutput"]
    assert _source(out.inputs[0]) == add
    a, b, _ = composite._add_sockets(add)
    assert _source(a) == rl and _source(b) == image_node

    composite.remove_layer(scene)
    assert scene.compositing_node_group is None
    assert len(bpy.data.node_groups) == 0 and not layer_images()


def test_apply_layer_joins_the_users_compositor(composite):
    scene = bpy.context.scene
    tree, rl, blur, out = users_compositor(scene)
    mine = {n.name for n in tree.nodes}

    composite.apply_layer(scene, layer_image())
    composite.apply_layer(scene, layer_image(value=3.0))

    assert scene.compositing_node_group == tree and len(bpy.data.node_groups) == 1
    assert len(layer_images()) == 1
    (add,), (image_node,) = our_nodes(tree, "add"), our_nodes(tree, "image")
    assert not our_nodes(tree, "render_layers")
    assert {n.name for n in tree.nodes} == mine | {add.name, image_node.name}
    assert _source(blur.inputs["Image"]) == rl  # the user's link is untouched
    assert _source(out.inputs[0]) == add
    a, b, _ = composite._add_sockets(add)
    assert _source(a) == blur and _source(b) == image_node
    assert np.allclose(image_pixels(image_node.image)[-1, :, :3], (3, 0, 0))

    composite.remove_layer(scene)
    assert scene.compositing_node_group == tree
    assert {n.name for n in tree.nodes} == mine
    assert _source(out.inputs[0]) == blur and _source(blur.inputs["Image"]) == rl
    assert not layer_images()


def test_apply_layer_feeds_an_unlinked_output_from_render_layers(composite):
    scene = bpy.context.scene
    tree = bpy.data.node_groups.new("Bare", "CompositorNodeTree")
    tree.interface.new_socket(name="Image", in_out='OUTPUT', socket_type="NodeSocketColor")
    out = tree.nodes.new("NodeGroupOutput")
    scene.compositing_node_group = tree
    composite.apply_layer(scene, layer_image())
    (add,), (rl,) = our_nodes(tree, "add"), our_nodes(tree, "render_layers")
    assert _source(out.inputs[0]) == add and _source(composite._add_sockets(add)[0]) == rl
    composite.remove_layer(scene)
    assert [n.name for n in tree.nodes] == [out.name] and not out.inputs[0].is_linked


def test_apply_layer_reads_the_written_exr(composite, tmp_path):
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.io.exr")
    path = tmp_path / "caustics.exr"
    layer = layer_image(value=5.0)
    imageio.write_exr(path, layer, {"method": "test"})
    img = composite.apply_layer(bpy.context.scene, layer, filepath=str(path))
    assert img.source == 'FILE' and bpy.path.abspath(img.filepath) == str(path)
    assert not img.packed_file
    assert np.allclose(image_pixels(img)[::-1, :, :3], layer)
    # Without a file the next bake is packed into the same datablock name.
    img = composite.apply_layer(bpy.context.scene, layer_image(value=1.0))
    assert [im.name for im in layer_images()] == [LAYER] and img.packed_file


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
    imageio = importlib.import_module(load_extension().__name__ + ".smbs_addon.io.exr")
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



def test_bake_operator_end_to_end(empty_bpy, addon, tmp_path, capsys):
    try:
        importlib.import_module(addon.__name__ + ".smbs_addon.baking.bake")
        importlib.import_module(addon.__name__ + ".smbs_addon.blender.export")
    except ImportError as e:
        pytest.skip(f"the render core cannot be imported yet: {e}")
    scene = mirror_scene()
    settings = scene.smbs_caustics
    settings.method, settings.spp, settings.seed = "reference", 1, 3
    settings.output_path = str(tmp_path / "layer.exr")

    capsys.readouterr()
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    # background mode: synchronous, with progress lines
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("SMBS Caustics:")]
    assert any("light 'Disk', batch 8/8" in ln for ln in lines), lines
    assert lines[-1].startswith("SMBS Caustics: 100.0% done in")
    assert (tmp_path / "layer.exr").is_file() and (tmp_path / "layer.json").is_file()
    stats = json.loads(settings.last_stats)
    assert stats and "Disk" in stats.get("lights", {"Disk": 1})
    img = bpy.data.images[LAYER]
    assert img.size[:] == (24, 16) and img.source == 'FILE' and not img.packed_file
    assert image_pixels(img)[..., :3].max() > 0.0, "the mirror should throw a caustic on the floor"
    assert our_nodes(scene.compositing_node_group, "image")[0].image == img

    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}  # a re-bake reuses everything
    assert len(layer_images()) == 1 and len(bpy.data.node_groups) == 1


def test_show_plan_before_baking(empty_bpy, addon, tmp_path):
    """Show Plan: the plan in words in the panel, nothing baked, nothing else changed."""
    scene = mirror_scene()
    assert bpy.ops.smbs.show_plan() == {'FINISHED'}
    assert scene.smbs_caustics.plan_text.splitlines() == ["Disk -> Mirror (reflection) -> Floor",
                                                          "Disk -> diffuse -> Mirror -> Floor (after a diffuse bounce)"]
    assert not layer_images() and scene.smbs_caustics.last_stats == ""


def test_bake_operator_with_nothing_to_bake(empty_bpy, addon, tmp_path):
    """No light: not a failure; an all-zero layer, a warning saying why, and the panel's plan."""
    scene = mirror_scene()
    bpy.data.objects.remove(scene.objects["Disk"])
    settings = scene.smbs_caustics
    settings.spp, settings.output_path = 1, str(tmp_path / "layer.exr")
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    stats = json.loads(settings.last_stats)
    assert stats["nothing_to_bake"] == "scene 'Scene' has no light"
    panels = importlib.import_module("smbs_caustics.ui.panels")
    assert panels.plan_lines(stats) == ["Nothing to bake: scene 'Scene' has no light. "
                                               "The caustic layer is all zero."]
    img = bpy.data.images[LAYER]
    assert img.size[:] == (24, 16) and not image_pixels(img)[..., :3].any()


def test_bake_operator_reports_scene_errors(empty_bpy, addon, tmp_path):
    try:
        importlib.import_module(addon.__name__ + ".smbs_addon.blender.export")
    except ImportError as e:
        pytest.skip(f"the render core cannot be imported yet: {e}")
    bpy.context.scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    with pytest.raises(RuntimeError, match="no camera"):  # ERROR reports raise in bpy.ops calls
        bpy.ops.smbs.bake_caustics()
    assert not (tmp_path / "layer.exr").exists()


def test_bake_operator_error_names_the_object(empty_bpy, addon, tmp_path):
    scene = mirror_scene()
    scene.camera.data.type = 'PANO'
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    with pytest.raises(RuntimeError, match="camera 'Camera': panoramic cameras are not supported"):
        bpy.ops.smbs.bake_caustics()
    assert not (tmp_path / "layer.exr").exists() and not layer_images()


# ---------------------------------------------------------------------------- nothing counted twice


def _flags(scene):
    return {ob.name: ((ob.data.cycles.is_caustics_light,) if ob.type == 'LIGHT' else
                      (ob.cycles.is_caustics_caster, ob.cycles.is_caustics_receiver))
            for ob in scene.objects}


def _bake(scene, tmp_path, **settings):
    s = scene.smbs_caustics
    s.method, s.spp, s.batches = "reference", 1, 2
    s.output_path = str(tmp_path / "layer.exr")
    for key, value in settings.items():
        setattr(s, key, value)
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    return s


def test_covered_scene_keeps_caustics_out_of_cycles(empty_bpy, addon, tmp_path):
    """No flags (AUTO): the bake covers the mirror, the floor and the light, so Cycles' own
    caustics go off; Remove Caustic Layer turns them back on. No flag of the user's changes."""
    scene = mirror_scene()
    flags = _flags(scene)
    cycles = scene.cycles
    assert cycles.caustics_reflective and cycles.caustics_refractive
    s = _bake(scene, tmp_path)
    assert not cycles.caustics_reflective and not cycles.caustics_refractive
    assert s.cycles_kept_out
    assert "none is counted twice" in s.cycles_note and "'Mirror'" in s.cycles_note
    _bake(scene, tmp_path)  # a re-bake keeps the first saved values
    assert s.saved_caustics_reflective and s.saved_caustics_refractive
    assert _flags(scene) == flags

    assert bpy.ops.smbs.remove_caustic_layer() == {'FINISHED'}
    assert cycles.caustics_reflective and cycles.caustics_refractive
    assert not s.cycles_kept_out and s.cycles_note == ""
    assert not layer_images() and scene.compositing_node_group is None
    assert _flags(scene) == flags


def test_a_mesh_light_is_covered_by_the_layer(empty_bpy, addon, tmp_path):
    """The mirror scene lit by an Emission panel beside its lamp: the panel is a mesh light of the layer,
    so the layer covers every light and Cycles' caustics go off (an emissive material kept them on, the
    note saying 'the layer has no mesh lights', before)."""
    scene = mirror_scene()
    glow = node_material("Glow", "ShaderNodeEmission", Strength=20.0)
    plane(scene, "Panel", 0.5, glow, (-2, 0.8, 1.5), (0, math.radians(-90), 0))
    s = _bake(scene, tmp_path)
    stats = json.loads(s.last_stats)
    assert list(stats["lights"]) == ["Disk", "Panel"], stats["lights"]
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out, s.cycles_note
    assert "'Panel'" in s.cycles_note


def test_the_last_bakes_warnings_stay_in_the_panel(empty_bpy, addon, tmp_path):
    """A bake's warnings (here: a rough mirror's Beckmann baked as GGX) are kept for the panel after the reports
    scroll away, the first few listed; a clean re-bake and Remove Caustic Layer clear them."""
    from types import SimpleNamespace

    scene = mirror_scene()
    mirror = bpy.data.materials["Mirror"].node_tree.nodes["Glossy BSDF"]
    mirror.inputs["Roughness"].default_value = 0.3
    mirror.distribution = "BECKMANN"
    s = _bake(scene, tmp_path)
    assert s.bake_warnings.splitlines() == [
        "material 'Mirror': the Beckmann distribution of 'Glossy BSDF' is baked as GGX (its blur of the caustic a "
        "little different from Cycles')"]
    drawn = []
    draw_all(addon, scene, drawn)
    assert "Last bake: 1 warning" in drawn and any("Beckmann" in str(d) for d in drawn)
    panels = addon.ui.panels
    many = "\n".join(f"warning {i}" for i in range(panels.WARNINGS_SHOWN + 3))
    drawn = []
    panels._draw_warnings(Layout(drawn), SimpleNamespace(region=None), many)
    assert f"Last bake: {panels.WARNINGS_SHOWN + 3} warnings" in drawn and "and 3 more (Info editor)" in drawn
    assert f"warning {panels.WARNINGS_SHOWN}" not in drawn
    mirror.inputs["Roughness"].default_value = 0.0
    _bake(scene, tmp_path)
    assert s.bake_warnings == ""
    s.bake_warnings = "something"
    assert bpy.ops.smbs.remove_caustic_layer() == {'FINISHED'}
    assert s.bake_warnings == ""


def test_users_switches_come_back_as_they_were(empty_bpy, addon, tmp_path):
    scene = mirror_scene()
    scene.cycles.caustics_reflective, scene.cycles.caustics_refractive = True, False
    _bake(scene, tmp_path)
    assert not scene.cycles.caustics_reflective
    bpy.ops.smbs.remove_caustic_layer()
    assert (scene.cycles.caustics_reflective, scene.cycles.caustics_refractive) == (True, False)


def test_partial_plan_leaves_cycles_alone_and_says_why(empty_bpy, addon, tmp_path):
    """A second, unflagged mirror while the first is flagged (AUTO honours caster flags): the layer
    does not cover it, so Cycles keeps its caustics and the note says what is counted where."""
    scene = mirror_scene()
    mirror = scene.objects["Mirror"]
    other = mirror.copy()
    other.name = "Mirror2"
    other.location.y += 2.0
    scene.collection.objects.link(other)
    mirror.cycles.is_caustics_caster = True
    flags = _flags(scene)

    s = _bake(scene, tmp_path)
    assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
    assert not s.cycles_kept_out
    assert "caster 'Mirror2' (not flagged Cast Shadow Caustics)" in s.cycles_note
    assert "counted twice" in s.cycles_note
    assert "Mirror2" not in s.bake_warnings  # the panel says it once, in the Cycles note
    assert _flags(scene) == flags

    # Covering everything (flags Off) turns Cycles' caustics off; going back restores them.
    _bake(scene, tmp_path, use_cycles_flags="OFF")
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out
    _bake(scene, tmp_path, use_cycles_flags="AUTO")
    assert scene.cycles.caustics_reflective and scene.cycles.caustics_refractive
    assert not s.cycles_kept_out
    assert _flags(scene) == flags


def _sky(scene, value):
    scene.world = world = bpy.data.worlds.new("Sky")
    world.color = (value,) * 3
    background = world.node_tree and world.node_tree.nodes.get("Background")
    if background:
        background.inputs["Color"].default_value = (value, value, value, 1.0)


def test_a_bright_world_is_a_light_of_the_layer(empty_bpy, addon, tmp_path):
    """A world of constant colour bright enough that its light through the mirror shows is baked
    as a light of its own (the layer then covers every light), so Cycles' caustics go off."""
    scene = mirror_scene()
    _sky(scene, 0.5)
    s = _bake(scene, tmp_path)
    stats = json.loads(s.last_stats)
    assert list(stats["lights"]) == ["Sky", "Disk"], stats["lights"]  # the world first, as exported
    assert any(w.startswith("Sky -> Mirror (reflection) -> Floor") for w in stats["plan"]["words"])
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out
    assert "from 'Sky', 'Disk'." in s.cycles_note
    assert "Too faint" not in s.cycles_note


def test_a_faint_world_does_not_keep_cycles_caustics_on(empty_bpy, addon, tmp_path):
    """A world of constant grey whose caustic can be at most 1% of the lamps' by the plan's pilots
    is not baked (plan.WORLD_MIN_SHARE), it is said so, and Cycles' caustics go off as without it."""
    scene = mirror_scene()
    _sky(scene, 0.0005)
    s = _bake(scene, tmp_path)
    stats = json.loads(s.last_stats)
    assert list(stats["lights"]) == ["Disk"]
    assert any(x["name"] == "Sky" and x["reason"].startswith("its caustic is too faint to show (")
               for x in stats["skipped"]), stats["skipped"]
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out
    assert "Too faint to see, rendered by neither: world 'Sky' through mirrors and glass (at most 0." in s.cycles_note


def test_an_unflagged_world_beside_flagged_lights_is_left_to_cycles(empty_bpy, addon, tmp_path):
    """Cycles' flags select the lights once one is flagged (AUTO): a bright world left unflagged
    is not baked, and Cycles keeps its caustics to render it; the note says how to change that.
    Under 1% of the layer's caustic at most (its colour x the floor's 0.8) it is dropped instead."""
    scene = mirror_scene()
    scene.objects["Disk"].data.cycles.is_caustics_light = True
    _sky(scene, 0.5)
    s = _bake(scene, tmp_path)
    mean = json.loads(s.last_stats)["noise"]["mean"]
    assert 0.5 * 0.8 > addon.operators.policy.WORLD_NEGLIGIBLE * mean
    assert scene.cycles.caustics_reflective and not s.cycles_kept_out
    assert "world 'Sky' (not flagged Shadow Caustics)" in s.cycles_note
    _sky(scene, 0.0005)
    s = _bake(scene, tmp_path)
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out
    assert f"world '{scene.world.name}' through mirrors and glass (at most" in s.cycles_note  # 'Sky.001'


def test_a_world_the_layer_cannot_read_is_named(empty_bpy, addon, tmp_path):
    """A Sky Texture world is black to the layer (warned at export): Cycles' caustics still go off
    (keeping them on would count the lamp's caustic twice), and the note names what neither
    renders then."""
    scene = mirror_scene()
    _sky(scene, 0.5)
    nt = scene.world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    nt.links.new(sky.outputs[0], nt.nodes["Background"].inputs["Color"])
    s = _bake(scene, tmp_path)
    assert list(json.loads(s.last_stats)["lights"]) == ["Disk"]
    assert not scene.cycles.caustics_reflective and s.cycles_kept_out
    assert (f"A node setup the layer cannot read (see the warnings), rendered by neither: world '{scene.world.name}' "
            "through mirrors and glass.") in s.cycles_note


def test_keep_out_of_cycles_off(empty_bpy, addon, tmp_path):
    scene = mirror_scene()
    s = _bake(scene, tmp_path, keep_out_of_cycles=False)
    assert scene.cycles.caustics_reflective and not s.cycles_kept_out
    assert "Keep Out of Cycles is off" in s.cycles_note


def _bumped(scene, material, bsdf, tmp_path):
    """Material's BSDF node bsdf with a Bump node (Distance 0.05) of a Noise Texture on its Normal; the
    scene's settings for a quick light-tracing bake to tmp_path (returned)."""
    nt = bpy.data.materials[material].node_tree
    bump = nt.nodes.new("ShaderNodeBump")
    nt.links.new(nt.nodes.new("ShaderNodeTexNoise").outputs[0], bump.inputs["Height"])
    nt.links.new(bump.outputs[0], nt.nodes[bsdf].inputs["Normal"])
    bump.inputs["Distance"].default_value = 0.05
    settings = scene.smbs_caustics
    settings.method, settings.spp, settings.seed = "reference", 1, 3
    settings.output_path = str(tmp_path / "layer.exr")
    return settings


def _data():
    return [sorted(x.name for x in coll) for coll in (bpy.data.scenes, bpy.data.objects, bpy.data.meshes,
                                                      bpy.data.materials)]


def _button_then_prepared(addon, settings, unsaid):
    """The Bake Caustics button (a layer with light in it, none of the words unsaid in its warnings),
    then the modal bake's start: the scene it prepared (cancelled again at once)."""
    assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert not any(word in settings.bake_warnings for word in unsaid), settings.bake_warnings
    assert image_pixels(bpy.data.images[LAYER])[..., :3].max() > 0.0
    bake_op = importlib.import_module(addon.__name__ + ".operators.bake")
    bake = bake_op.ModalBake(lambda level, message: None)
    assert bake.start(bpy.context)
    data = bake.prep.data
    bake.cancel()
    assert bake.step(bpy.context, 'TIMER') == {'CANCELLED'}
    return data


def test_bake_operator_bakes_a_bumped_mirror(empty_bpy, addon, tmp_path):
    """The button on a mirror whose Normal is a Bump node of a Noise Texture: the export's own Cycles
    bake of the Height (bump.py) runs inside the operator, synchronous here and from the modal
    operator's start, and leaves no scene, object, mesh or material of its own behind."""
    scene = mirror_scene()
    settings = _bumped(scene, "Mirror", "Glossy BSDF", tmp_path)
    before = _data()
    sc = _button_then_prepared(addon, settings, ("Bump", "could not be baked"))
    normals = sc.tri_normals[sc.tri_object == sc.object_names.index("Mirror")]
    assert len(normals) > 10_000 and np.ptp(normals.reshape(-1, 3), axis=0).max() > 0.01  # cut finer, bent
    assert _data() == before


def test_bake_operator_bakes_a_bumped_floor(empty_bpy, addon, tmp_path):
    """The button on a floor whose Diffuse BSDF's Normal is a Bump node of a Noise Texture: the
    export's render of the camera's view (cycles_passes.view_maps) runs inside the operator and leaves no
    scene, object, mesh, material or image of its own behind; the floor is read as bumped."""
    scene = mirror_scene()
    settings = _bumped(scene, "Floor", "Diffuse BSDF", tmp_path)
    before = _data()
    sc = _button_then_prepared(addon, settings, ("Floor", "could not be rendered"))
    assert sc.mat_view_bump[sc.mat_names.index("Floor")] and sc.view_normals.shape == (16 * 4, 24 * 4, 3)
    assert _data() == before and sorted(im.name for im in bpy.data.images) == [LAYER]
