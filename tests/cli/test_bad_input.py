"""Bad input gets one clear answer (issue 5, part 4).

Each case asserts the exact message, which names the object (scene, light,
material, file) and the problem. A bake that fails or is cancelled leaves the
Blender scene exactly as it was; EXR files are written atomically (a temporary
file, then a rename) and a failing write leaves neither half an image nor the
temporary file; a re-bake replaces the layer, never stacks a second one.
"""
from __future__ import annotations

import dataclasses
import importlib
import math
import os
import sys
import zipfile

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeCancelled, BakeSettings, Scene, SceneError, bake
bake_module = importlib.import_module("smbs_addon.baking.engine")  # where the film's memory is checked
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.io.exr import read_exr, write_exr
from testkit.cli import one_error_line, run


def mirror_parts(b, light=True, caster=True, receiver=True):
    """The tiny mirror scene of testkit/scenes.py, piece by piece."""
    b.material("floor", "diffuse", color=(0.8,) * 3)
    b.material("mirror", "conductor", color=(0.9,) * 3)
    if receiver:
        b.plane("Floor", (0, 0, 0), 10, "floor")
    if caster:
        b.plane("Mirror", (0, 0, 1.5), 1.5, "mirror", normal=np.array([-1, 0, -1]) / math.sqrt(2))
    if light:
        b.light("Disk", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), power=100.0, shape="DISK", size=0.5)
    b.set_camera((0, -6, 5), (-0.2, 0, 0), lens=35, resolution_x=32, resolution_y=24)
    return b


def bake_error(scene, **kw) -> str:
    with pytest.raises(SceneError) as e:
        bake(scene, BakeSettings(**{"spp": 1, "batches": 2, **kw}))
    return str(e.value)


# ------------------------------------------------------------------------ nothing to bake
def nothing_to_bake(scene) -> str:
    """A scene with no caustic to bake is not an error (issue 12): the layer is all zero,
    no caustic ray is traced, and the statistics say why."""
    res = bake(scene, BakeSettings(spp=1, batches=2))
    assert not res.image.any() and res.image.shape == (24, 32, 3)
    assert res.stats["lights"] == {} and res.stats["stopped_by"] == "nothing_to_bake"
    assert res.stats["rays"] == res.stats["plan"].get("rays", 0)
    assert res.stats["plan"]["words"] == [f"Nothing to bake: {res.stats['nothing_to_bake']}. "
                                          "The caustic layer is all zero."]
    return res.stats["nothing_to_bake"]


def test_no_light():
    scene = mirror_parts(SceneBuilder("Dark"), light=False).build()
    assert nothing_to_bake(scene) == "scene 'Dark' has no light"


def test_no_caster():
    scene = mirror_parts(SceneBuilder("Bare"), caster=False).build()
    assert nothing_to_bake(scene) == "scene 'Bare' has no caustic caster: no object with a glossy or glass material"


def test_no_caster_among_the_flagged_objects():
    b = mirror_parts(SceneBuilder("Flagged"), caster=False)
    b.plane("Wall", (3, 0, 1), 2, "floor", normal=(-1, 0, 0), caster=True)  # flagged, but diffuse
    b.plane("Mirror", (0, 0, 1.5), 1.5, "mirror", normal=np.array([-1, 0, -1]) / math.sqrt(2))  # not flagged
    assert nothing_to_bake(b.build()) == ("scene 'Flagged' has no caustic caster: no object with a glossy or "
                                          "glass material is flagged 'Cast Shadow Caustics'")


def test_no_receiver():
    scene = mirror_parts(SceneBuilder("Void"), receiver=False).build()
    assert nothing_to_bake(scene) == "scene 'Void' has no caustic receiver: no diffuse object"


# --------------------------------------------------------------------------- zero-size lights
def test_zero_size_area_light_is_skipped_with_a_reason():
    b = mirror_parts(SceneBuilder("Two lights"))
    b.light("Flat", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), power=100.0, shape="RECTANGLE",
            size=(0.5, 0.0))
    res = bake(b.build(), BakeSettings(method="mnee", spp=1, batches=2))
    assert {"kind": "light", "name": "Flat", "reason": "zero size"} in res.stats["skipped"]
    assert list(res.stats["lights"]) == ["Disk"] and res.image.max() > 0


def test_only_a_zero_size_light_bakes_nothing():
    b = mirror_parts(SceneBuilder("Pinhole"), light=False)
    b.light("Dot", "AREA", location=(-2, 0, 1.5), target=(0, 0, 1.5), power=100.0, shape="DISK", size=0.0)
    assert nothing_to_bake(b.build()) == "no light can cast caustics ('Dot': zero size)"


def test_zero_radius_point_light_is_a_point_not_an_error():
    b = mirror_parts(SceneBuilder("Point"), light=False)
    b.light("Bulb", "POINT", location=(-2, 0, 1.5), power=100.0, radius=0.0)
    res = bake(b.build(), BakeSettings(method="sms", spp=1, batches=2))
    assert res.stats["skipped"] == [] and res.image.max() > 0 and np.all(np.isfinite(res.image))


# ------------------------------------------------------------------------------ settings and arrays
def test_negative_clamp():
    scene = scenes.mirror_scene(resolution=(8, 6))
    assert bake_error(scene, clamp_g=-1.0) == "clamp_g must be 0 (off) or a positive luminance, not -1.0"
    assert bake_error(scene, clamp_g=float("nan")) == "clamp_g must be 0 (off) or a positive luminance, not nan"


def test_nan_normals_name_the_object():
    """A NaN in a triangle's normals names the object that holds the triangle (issue 59: it named the
    internal array 'tri_normals')."""
    scene = scenes.mirror_scene(resolution=(8, 6))
    scene.tri_normals[3, 1] = np.nan
    owner = scene.object_names[int(scene.tri_object[3])]
    with pytest.raises(SceneError) as e:
        scene.validate()
    assert str(e.value) == f"object '{owner}': its normals hold NaN or infinite values (1 triangle)"


def _invalid(scene) -> str:
    with pytest.raises(SceneError) as e:
        scene.validate()
    return str(e.value)


def test_out_of_range_values_a_fuzz_found_are_refused_with_their_name():
    """Whole-bake fuzzing (stop 34, 956 bakes) found these passing validate(): a render border
    outside 0..1 let the splat kernels write outside the film (a segfault or a heap corruption),
    a border of NaN a bare ValueError, a negative colour negative energy, a power of 1e38 an
    infinite variance and one of 1e200 a FloatingPointError naming nothing, and huge Light Paths
    limits or filter widths a MemoryError or minutes of work."""
    def fresh():
        return scenes.mirror_scene(resolution=(8, 6))

    sc = fresh()
    sc.camera.use_border, sc.camera.border = True, (-0.5, 1.5, 0.0, 1.0)
    assert _invalid(sc) == ("camera render border (-0.5, 1.5, 0.0, 1.0): expected min x, max x, min y, max y, "
                            "each a fraction of the frame from 0 to 1")
    sc.camera.border = (0.0, float("nan"), 0.0, 1.0)
    assert _invalid(sc).startswith("camera render border (0.0, nan, 0.0, 1.0)")
    sc.camera.use_border = False
    sc.validate()  # a border that is not used is not looked at, as in Blender
    sc = fresh()
    sc.mat_color[0] = (0.8, -0.5, 0.8)
    assert _invalid(sc) == "material 'floor': colour (0.8, -0.5, 0.8) must be between 0 and 1e+06"
    sc = fresh()
    sc.mat_reflect_color[1] = (1e300, 0.0, 0.0)
    assert _invalid(sc) == "material 'mirror': reflection colour (1e+300, 0.0, 0.0) must be between 0 and 1e+06"
    sc = fresh()
    sc.mat_layer = np.zeros((len(sc.mat_kind), 8))
    sc.mat_layer[0] = (1.5, float("nan"), 1.0, 1.0, 0.0, 0.0, 0.0, 0.0)
    assert _invalid(sc) == ("material 'floor': its glossy layer (index, roughness, tint, weight, diffuse "
                            "roughness, coat weight, coat index, coat roughness) must be finite numbers from 0 to 1e+06")
    sc.mat_layer = np.zeros((1, 8))
    assert _invalid(sc) == f"scene array 'mat_layer' must be ({len(sc.mat_kind)}, 8) or empty"
    sc = fresh()
    sc.mat_textured = np.array([True, True])  # the floor may be; the mirror may not
    assert _invalid(sc) == "material 'mirror': only a diffuse material can be textured"
    sc.mat_textured = np.array([True])
    assert _invalid(sc) == f"scene array 'mat_textured' must have one entry per material ({len(sc.mat_kind)}) or none"
    sc = fresh()
    sc.light_color[0] = (1e38, 1e38, 1e38)
    assert _invalid(sc) == ("light 'Disk': power 1e+38 is beyond 1e+20, more than a float32 caustic layer "
                            "can hold")
    sc = fresh()
    sc.light_type[0] = 7
    assert _invalid(sc) == "light 'Disk': unknown type 7"
    sc = fresh()
    sc.light_size[0] = (-0.5, 0.5)
    assert _invalid(sc) == "light 'Disk': negative size, radius, angle or spot size"
    sc = fresh()
    sc.light_spread[0] = 10.0
    assert _invalid(sc) == "light 'Disk': spread 10 radians must be from 0 to pi (180 degrees)"
    sc = fresh()
    sc.light_paths = np.array([-1, 2**40, -1, -1])
    assert _invalid(sc) == "Light Paths bounces (-1, 1099511627776, -1, -1): each at most 1024 (Blender's limit)"
    sc = fresh()
    sc.camera.filter_width = 1e4
    assert _invalid(sc) == "camera filter_width 10000 pixels: Cycles' pixel filter is at most 10"
    sc = fresh()
    sc.camera.matrix_world = np.diag([1.0, 0.0, 1.0, 1.0])
    assert _invalid(sc) == "camera: its matrix is degenerate (an axis scaled to zero?), so it has no view direction"
    sc = fresh()
    sc.camera.type = "PERSP"
    assert _invalid(sc) == "camera type 'PERSP' not supported (perspective or orthographic)"


def test_a_camera_clipping_everything_bakes_nothing_and_says_so():
    sc = scenes.mirror_scene(resolution=(32, 24))
    sc.camera.clip_start, sc.camera.clip_end = 50.0, 10.0
    assert nothing_to_bake(sc) == "the camera's clip start (50) is not before its clip end (10): it sees nothing"


def test_a_light_scaled_to_zero_is_skipped_with_its_reason():
    b = mirror_parts(SceneBuilder("Flat sun"))
    b.light("Sun", "SUN", location=(0, 0, 5), target=(0, 0, 0), power=3.0)
    sc = b.build()
    sc.light_matrix[1][:3, 2] = 0.0  # its direction gone (an object scaled to 0 in z)
    res = bake(sc, BakeSettings(method="mnee", spp=1, batches=2))
    assert {"kind": "light", "name": "Sun", "reason": "its object is scaled to zero along an axis the light "
            "needs (no direction or no area)"} in res.stats["skipped"]
    assert list(res.stats["lights"]) == ["Disk"] and np.all(np.isfinite(res.image))


def test_a_loose_solver_threshold_or_a_strict_uniqueness_is_refused():
    """Each would bias the layer: the Bernoulli trials would not know two walks to one solution
    for the same one (the glass sphere: threshold 1e-3 with the default uniqueness +18%, 1e-2
    35x and a minute's work)."""
    scene = scenes.mirror_scene(resolution=(8, 6))
    assert bake_error(scene, solver_threshold=1e-3).startswith(
        "solver_threshold 0.001 is above 1e-05 radians: a walk would stop that far from its solution")
    assert bake_error(scene, solver_threshold=1e-5, uniqueness=1e-10).startswith(
        "uniqueness 1e-10 is too strict for solver_threshold 1e-05: two walks to one solution end up")
    bake(scene, BakeSettings(spp=1, batches=2, solver_threshold=1e-5, uniqueness=1e-9))


# --------------------------------------------------------------------- resolution too large
def test_resolution_too_large_is_refused_before_anything_is_allocated():
    scene = scenes.mirror_scene()
    scene.camera = dataclasses.replace(scene.camera, resolution_x=32000, resolution_y=18000,
                                       resolution_percentage=50)
    assert bake_error(scene, batches=8) == (
        "scene 'mirror': a 16000 x 9000 caustic layer needs about 79.4 GiB for its film (8 batches), more "
        "than the 8 GiB limit; lower the resolution (or its percentage) or the number of batches")


def test_memory_estimate_is_the_film(monkeypatch):
    """The estimate counts what the film holds: 3 float64 accumulators per pixel and channel,
    the image and variance (float64, then float32), a float32 image per batch, and with stratified
    samples (the default) each replicate's sum and mean (3 float64 each)."""
    assert bake_module.film_memory(64, 48, 8) == 64 * 48 * (9 * 8 + 6 * 8 + 6 * 4) + 2 * 8 * 64 * 48 * 4
    assert bake_module.film_memory(64, 48, 8, textured=True) == bake_module.film_memory(64, 48, 8) + 64 * 48 * 120
    assert bake_module.film_memory(64, 48, 8, replicates=8) == bake_module.film_memory(64, 48, 8) + 8 * 64 * 48 * 48
    monkeypatch.setattr(bake_module, "MEMORY_BUDGET", bake_module.film_memory(16, 12, 2, replicates=2))
    scene = scenes.mirror_scene(resolution=(16, 12))
    res = bake(scene, BakeSettings(method="mnee", spp=1, batches=2))  # exactly at the limit: fine
    assert res.image.shape == (12, 16, 3)
    scene.camera = dataclasses.replace(scene.camera, resolution_x=17)
    assert bake_error(scene, method="mnee").startswith("scene 'mirror': a 17 x 12 caustic layer needs about ")


# ------------------------------------------------------------------------------- corrupt .npz
@pytest.fixture
def saved(tmp_path):
    path = tmp_path / "scene.npz"
    scenes.mirror_scene(resolution=(8, 6)).save(path)
    return path


def load_error(path) -> str:
    with pytest.raises(SceneError) as e:
        Scene.load(path)
    return str(e.value)


def _rewrite(path, **changes):
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(changes)
    for k, v in list(arrays.items()):
        if v is None:
            del arrays[k]
    np.savez(path, **arrays)


def test_corrupt_npz_messages(saved, tmp_path):
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"PK\x03\x04 certainly not a scene")
    assert load_error(junk) == f"{junk}: not a readable scene .npz (not a zip archive)"
    half = tmp_path / "half.npz"
    half.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    assert load_error(half) == f"{half}: not a readable scene .npz (not a zip archive)"
    _rewrite(saved, tri_vertices=None)
    assert load_error(saved) == f"{saved}: missing array 'tri_vertices'"
    _rewrite(saved, format_version=np.asarray(7), tri_vertices=np.zeros((2, 3, 3)))
    assert load_error(saved) == f"{saved}: scene format version 7, expected 1"
    _rewrite(saved, format_version=np.asarray(1), light_names=np.array([object()], dtype=object))
    assert load_error(saved) == (f"{saved}: not a readable scene .npz "
                                 "(Object arrays cannot be loaded when allow_pickle=False)")


def test_corrupt_npz_on_the_command_line(saved, tmp_path):
    with zipfile.ZipFile(saved, "a") as z, pytest.warns(UserWarning, match="Duplicate name"):
        z.writestr("tri_uvs.npy", b"\x93NUMPY garbage")  # a well-formed zip, a member that is no array
    out = tmp_path / "x.exr"
    proc = run("bake", saved, "--out", out)
    assert proc.returncode == 1
    line = one_error_line(proc)
    assert line.startswith(f"smbs_addon: error: {saved}: not a readable scene .npz (")
    assert not out.exists() and not list(tmp_path.glob(".*tmp*"))


# ------------------------------------------------------------------------ unwritable output
def test_output_that_is_a_folder(tmp_path):
    folder = tmp_path / "layer.exr"
    folder.mkdir()
    with pytest.raises(SceneError) as e:
        write_exr(folder, np.ones((4, 4, 3)))
    assert str(e.value) == f"cannot write '{folder}': it is a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layer.exr"] and not any(folder.iterdir())


@pytest.fixture(scope="module")
def npz(tmp_path_factory):
    path = tmp_path_factory.mktemp("bad_input") / "mirror.npz"
    scenes.mirror_scene(resolution=(16, 12)).save(path)
    return path


def test_unwritable_output_on_the_command_line(npz, tmp_path):
    folder = tmp_path / "out.exr"
    folder.mkdir()
    proc = run("bake", npz, "--out", folder, "--spp", 1)
    assert proc.returncode == 3
    assert one_error_line(proc) == f"smbs_addon: error: output '{folder}' is a folder"
    afile = tmp_path / "notes.txt"
    afile.write_text("a file, not a folder")
    proc = run("bake", npz, "--out", afile / "x.exr", "--spp", 1)
    assert proc.returncode == 3
    assert one_error_line(proc) == f"smbs_addon: error: output folder '{afile}' is a file"
    # refused before the bake, root or not: a file is made there and removed (tests/faults/test_fault_outputs.py)
    proc = run("bake", npz, "--out", "/proc/x.exr", "--spp", 1)
    assert proc.returncode == 3
    assert one_error_line(proc).startswith("smbs_addon: error: output folder '/proc' is not writable (")


class _FailingOutput:
    """An OpenImageIO output that writes half the scanlines, then fails (a full disk, a crash)."""

    def __init__(self, real, exc):
        self.real, self.exc = real, exc

    def open(self, name, spec):
        return self.real.open(name, spec)

    def write_image(self, img):
        h = img.shape[0] // 2
        self.real.write_scanlines(0, h, 0, np.ascontiguousarray(img[:h]))
        raise self.exc

    def geterror(self):
        return self.real.geterror()

    def close(self):
        return self.real.close()


@pytest.mark.parametrize("exc", [OSError(28, "No space left on device"), KeyboardInterrupt()])
def test_a_failing_write_leaves_no_half_image_and_no_temporary_file(tmp_path, monkeypatch, exc):
    import OpenImageIO as oiio

    path = tmp_path / "layer.exr"
    write_exr(path, np.full((8, 6, 3), 0.25), {"method": "first"})
    before = path.read_bytes()
    real_create = oiio.ImageOutput.create

    class FakeImageOutput:
        @staticmethod
        def create(name):
            return _FailingOutput(real_create(name), exc)

    monkeypatch.setattr(oiio, "ImageOutput", FakeImageOutput)
    with pytest.raises(type(exc)):
        write_exr(path, np.full((8, 6, 3), 0.75), {"method": "second"})
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layer.exr"]  # no temporary file
    assert path.read_bytes() == before  # the old image, whole
    img, meta = read_exr(path)
    assert np.all(img == 0.25) and meta["method"] == "first"


def test_rebake_on_the_command_line_replaces(npz, tmp_path):
    out = tmp_path / "layer.exr"
    for seed in (1, 2):
        proc = run("bake", npz, "--method", "mnee", "--spp", 1, "--batches", 2, "--seed", seed,
                   "--out", out, "--quiet")
        assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layer.exr", "layer.json"]
    img, meta = read_exr(out)
    assert meta["seed"] == 2
    again = bake(Scene.load(npz), BakeSettings(method="mnee", spp=1, batches=2, seed=2))
    assert np.array_equal(img, again.image)


# =========================================================================== in Blender
bpy = pytest.importorskip("bpy")


from testkit.blend import mirror_scene, node_material, plane  # noqa: E402


def snapshot(matrices=True):
    """Everything a bake could touch: every datablock by name, every object's transform and
    caustic flags, the scene's render, Cycles and add-on settings, and the compositor.
    (The view layer is evaluated first, so matrix_world is up to date either way.)"""
    bpy.context.view_layer.update()
    ids = {}
    for attr in dir(bpy.data):
        coll = getattr(bpy.data, attr, None)
        if isinstance(coll, bpy.types.bpy_prop_collection) and attr not in ("window_managers", "screens",
                                                                              "workspaces"):
            ids[attr] = sorted(x.name_full for x in coll)
    objects = {ob.name: ([tuple(r) for r in ob.matrix_world] if matrices else None, tuple(ob.location),
                         tuple(ob.rotation_euler), tuple(ob.scale), ob.cycles.is_caustics_caster,
                         ob.cycles.is_caustics_receiver)
               for ob in bpy.data.objects}
    scenes_ = {}
    for sc in bpy.data.scenes:
        r = sc.render
        props = getattr(sc, "smbs_caustics", None)
        scenes_[sc.name] = dict(
            render=(r.resolution_x, r.resolution_y, r.resolution_percentage, r.use_compositing),
            cycles=(sc.cycles.caustics_reflective, sc.cycles.caustics_refractive),
            compositor=getattr(sc, "compositing_node_group", None) and sc.compositing_node_group.name,
            props=None if props is None else {p.identifier: str(getattr(props, p.identifier))
                                              for p in props.bl_rna.properties if p.identifier != "rna_type"})
    return dict(ids=ids, objects=objects, scenes=scenes_,
                nodes={m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree})


@pytest.fixture
def fresh_bpy():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield bpy


def test_no_camera(fresh_bpy):
    from smbs_addon.blender.export import export_scene

    scene = mirror_scene(camera=False)
    scene.name = "Camera-less"
    with pytest.raises(SceneError) as e:
        export_scene(scene)
    assert str(e.value) == "scene 'Camera-less' has no camera"


def test_unsupported_material_nodes_are_named(fresh_bpy):
    from smbs_addon.blender.export import export_scene

    scene = mirror_scene()
    toon = node_material("Cartoon", "ShaderNodeBsdfToon", (1.0, 0.5, 0.2))
    plane(scene, "Toon", 1, toon, (2, 2, 0.5))
    textured = node_material("Marbled Glass", "ShaderNodeBsdfGlass", (1.0, 1.0, 1.0))
    tex = textured.node_tree.nodes.new("ShaderNodeTexNoise")
    glass_node = next(n for n in textured.node_tree.nodes if n.type == "BSDF_GLASS")
    textured.node_tree.links.new(tex.outputs["Color"], glass_node.inputs["Color"])
    plane(scene, "Pane", 1, textured, (-2, 2, 0.5))
    warnings = []
    data = export_scene(scene, warn=warnings.append)
    assert warnings == [
        "material 'Cartoon': node 'Toon BSDF' is not supported; treated as diffuse (albedo 0.8)",
        "material 'Marbled Glass': input 'Color' of node 'Glass BSDF' is driven by node 'Noise Texture' "
        "(a constant is needed); treated as diffuse (albedo 0.8)",
    ]
    res = bake(data, BakeSettings(method="mnee", spp=1, batches=2))  # the rest still bakes
    assert res.image.max() > 0 and np.all(np.isfinite(res.image))


def test_library_linked_scene_exports_read_only(fresh_bpy, tmp_path):
    """A whole scene linked from a library (no window shows it, nothing in it is editable):
    the export evaluates it without touching it, and it bakes like a local one."""
    from smbs_addon.blender.export import export_scene

    scene = mirror_scene()
    scene.name = "Library Scene"
    lib = tmp_path / "library.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(lib))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(lib), link=True) as (_, dst):
        dst.scenes = ["Library Scene"]
    linked = dst.scenes[0]
    assert linked.library is not None and bpy.context.scene != linked
    assert all(ob.library is not None for ob in linked.objects)
    # nothing evaluates a scene no window shows: its matrices are stale until the export does
    before = snapshot(matrices=False)
    warnings = []
    data = export_scene(linked, warn=warnings.append)
    assert warnings == []
    assert data.object_names == ["Floor", "Mirror"] and data.light_names == ["Disk"]
    res = bake(data, BakeSettings(method="mnee", spp=1, batches=2))
    assert res.image.max() > 0
    local = export_scene(linked)  # twice: the same arrays
    assert np.array_equal(local.tri_vertices, data.tri_vertices)
    assert snapshot(matrices=False) == before


def test_zero_size_light_from_blender_is_skipped_with_its_reason(fresh_bpy):
    from smbs_addon.blender.export import export_scene

    scene = mirror_scene()
    data = bpy.data.lights.new("Sliver", 'AREA')
    data.shape, data.size, data.size_y = 'RECTANGLE', 0.5, 0.0
    ob = bpy.data.objects.new("Sliver", data)
    ob.location, ob.rotation_euler = (-2, 0, 1.0), (0, math.radians(-90), 0)
    scene.collection.objects.link(ob)
    res = bake(export_scene(scene), BakeSettings(method="mnee", spp=1, batches=2))
    assert {"kind": "light", "name": "Sliver", "reason": "zero size"} in res.stats["skipped"]


# ----------------------------------------------------------- a failed or cancelled bake changes nothing
def _extension_core(addon):
    return sys.modules[addon.__name__ + ".smbs_addon.baking.bake"]


def test_failed_bake_leaves_the_scene_as_it_was(fresh_bpy, addon, tmp_path):
    scene = mirror_scene()
    scene.camera = None
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    before = snapshot()
    with pytest.raises(RuntimeError, match=r"scene 'Scene' has no camera"):
        bpy.ops.smbs.bake_caustics()
    assert snapshot() == before
    assert list(tmp_path.iterdir()) == []


def test_too_large_resolution_leaves_the_scene_as_it_was(fresh_bpy, addon, tmp_path):
    scene = mirror_scene()
    scene.render.resolution_x, scene.render.resolution_y = 16000, 9000
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    scene.smbs_caustics.batches = 8
    before = snapshot()
    with pytest.raises(RuntimeError, match=r"scene 'Scene': a 16000 x 9000 caustic layer needs about 79\.4 GiB "
                                           r"for its film \(8 batches\), more than the 8 GiB limit"):
        bpy.ops.smbs.bake_caustics()
    assert snapshot() == before
    assert list(tmp_path.iterdir()) == []


def test_bake_that_crashes_leaves_the_scene_as_it_was(fresh_bpy, addon, tmp_path, monkeypatch):
    core = _extension_core(addon)
    real = core.bake

    def crashing(data, settings, progress=None, cancel=None):
        def progress_then_crash(fraction, message=""):
            if fraction > 0.3:
                raise MemoryError("out of memory half-way")
        return real(data, settings, progress=progress_then_crash, cancel=cancel)

    monkeypatch.setattr(core, "bake", crashing)
    scene = mirror_scene()
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    scene.smbs_caustics.method, scene.smbs_caustics.spp = "mnee", 1
    before = snapshot()
    with pytest.raises(RuntimeError, match="Bake failed: MemoryError: out of memory half-way"):
        bpy.ops.smbs.bake_caustics()
    assert snapshot() == before
    assert list(tmp_path.iterdir()) == []


def test_cancelled_bake_leaves_the_scene_as_it_was(fresh_bpy, addon, tmp_path, monkeypatch):
    from smbs_addon.blender.export import export_scene

    scene = mirror_scene()
    scene.smbs_caustics.output_path = str(tmp_path / "layer.exr")
    before = snapshot()
    data = export_scene(scene)
    with pytest.raises(BakeCancelled, match="^bake cancelled$"):
        bake(data, BakeSettings(method="smbs", spp=1, batches=2), cancel=lambda: True)
    assert snapshot() == before

    # the same through the operator: its bake is cancelled at the core's first check
    core = _extension_core(addon)
    real = core.bake
    monkeypatch.setattr(core, "bake", lambda data, settings, progress=None, cancel=None:
                        real(data, settings, progress=progress, cancel=lambda: True))
    assert bpy.ops.smbs.bake_caustics() == {'CANCELLED'}
    assert snapshot() == before
    assert list(tmp_path.iterdir()) == []


def test_operator_rebake_replaces(fresh_bpy, addon, tmp_path):
    scene = mirror_scene()
    props = scene.smbs_caustics
    props.output_path = str(tmp_path / "layer.exr")
    props.method, props.spp, props.batches = "mnee", 1, 2
    for seed in (1, 2):
        props.seed = seed
        assert bpy.ops.smbs.bake_caustics() == {'FINISHED'}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layer.exr", "layer.json"]
    assert read_exr(tmp_path / "layer.exr")[1]["seed"] == 2
    ours = [img for img in bpy.data.images if img.get("smbs_caustics")]
    assert len(ours) == 1
