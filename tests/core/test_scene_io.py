"""Scene save/load (.npz) and validate() (smbs_addon/scene.py)."""
import dataclasses
import math
import re
import zipfile

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder, look_at
from smbs_addon.core.errors import SceneError
from smbs_addon.scene.arrays import Scene


def full_scene() -> Scene:
    """Every light type (the emitter panel a mesh light) and area shape, every material kind, a smooth mesh with UVs,
    a non-default camera."""
    b = SceneBuilder("everything")
    floor = b.material("Floor", "diffuse", color=(0.8, 0.7, 0.6), textured=True)
    metal = b.material("Gold", "conductor", color=(1.0, 0.8, 0.3), fresnel=S.FRESNEL_SCHLICK,
                       metal=(0.0, 0.4, 1.2, 0.0, 0.0, 0.0))  # an F82-Tint edge tint
    glass = b.material("Glass", "dielectric", color=(0.9, 1.0, 0.95), ior=1.45,
                       reflect_color=(1.0, 0.9, 0.9))
    lamp = b.material("Lamp", "emitter", color=(1.0, 1.0, 0.5), strength=7.5)
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (0, 0, 1), 1.5, metal, normal=(1, 0, -1), caster=True)
    b.uv_sphere("Ball", (1, 1, 1), 0.5, glass, segments=12, rings=6, caster=True, receiver=True)
    b.plane("Panel", (0, 0, 4), 0.5, lamp, normal=(0, 0, -1))
    b.light("Point", "POINT", location=(1, 2, 3), power=500.0, radius=0.1, soft_falloff=True,
            lit=("Ball", "Floor"))  # Light Linking
    b.light("Spot", "SPOT", location=(-1, 0, 3), target=(0, 0, 0), power=800.0, color=(1, 0.5, 0.25),
            spot_size=math.radians(30), spot_blend=0.3, radius=0.05)
    for shape, size in (("SQUARE", 0.5), ("RECTANGLE", (0.5, 0.25)), ("DISK", 0.4), ("ELLIPSE", (0.4, 0.2))):
        b.light(f"Area {shape}", "AREA", location=(0, -2, 3), target=(0, 0, 0), power=100.0, shape=shape,
                size=size, spread=math.radians(60))
    b.light("Sun", "SUN", location=(0, 0, 10), target=(0.3, 0.1, 0), power=3.0, angle=math.radians(0.5),
            caustics=False)
    b.set_camera((0, -6, 5), (0, 0, 0), type=S.ORTHO, lens=42.0, sensor_width=30.0, sensor_height=20.0,
                 sensor_fit="VERTICAL", ortho_scale=4.5, shift_x=0.1, shift_y=-0.05, clip_start=0.05,
                 clip_end=250.0, resolution_x=320, resolution_y=200, resolution_percentage=50,
                 pixel_aspect_x=1.0, pixel_aspect_y=1.25, use_border=True, border=(0.1, 0.6, 0.2, 0.9),
                 use_crop_to_border=True, filter_width=2.25)
    b.world_color = np.array([0.01, 0.02, 0.03])
    return b.build()


def assert_scenes_equal(a: Scene, b: Scene):
    for f in dataclasses.fields(Scene):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "camera":
            for cf in dataclasses.fields(S.Camera):
                cx, cy = getattr(x, cf.name), getattr(y, cf.name)
                if isinstance(cx, np.ndarray):
                    assert np.array_equal(cx, cy), cf.name
                else:
                    assert cx == cy and type(cx) is type(cy), (cf.name, cx, cy)
        elif isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), f.name
        else:
            assert x == y and type(x) is type(y), (f.name, x, y)


def test_round_trip_every_field(tmp_path):
    sc = full_scene()
    assert sc.n_lights == 8 and set(sc.light_type.tolist()) == {S.POINT, S.SPOT, S.AREA, S.SUN, S.MESH}
    assert sc.light_names[-1] == "Panel" and sc.tri_light.max() == 7  # the emitter panel: a mesh light
    assert set(sc.light_shape[sc.light_type == S.AREA].tolist()) == {S.SQUARE, S.RECTANGLE, S.DISK, S.ELLIPSE}
    assert set(sc.mat_kind.tolist()) == {S.DIFFUSE, S.CONDUCTOR, S.DIELECTRIC, S.EMITTER}
    assert sc.mat_textured.tolist() == [True, False, False, False]
    assert sc.light_links.shape == (8, 4) and sc.lit_by(0).tolist() == [True, False, True, False]
    path = tmp_path / "scene.npz"
    sc.save(path)
    back = Scene.load(path)
    assert_scenes_equal(sc, back)
    assert back.camera.border == (0.1, 0.6, 0.2, 0.9)
    assert back.camera.width == 160 and back.camera.height == 100
    # saving the loaded scene again gives the same arrays
    path2 = tmp_path / "again.npz"
    back.save(path2)
    assert_scenes_equal(sc, Scene.load(path2))
    assert not list(tmp_path.glob("*.tmp*")), "temporary files left behind"


def test_round_trip_empty_scene(tmp_path):
    sc = S.empty_scene(name="nothing")
    sc.save(tmp_path / "e.npz")
    back = Scene.load(tmp_path / "e.npz")
    assert_scenes_equal(sc, back)
    assert back.object_names == [] and back.n_tris == 0 and back.n_lights == 0


# -------------------------------------------------------------------- corrupt
@pytest.fixture
def saved(tmp_path):
    path = tmp_path / "good.npz"
    full_scene().save(path)
    return path


def load_error(path) -> str:
    with pytest.raises(SceneError) as e:
        Scene.load(path)
    msg = str(e.value)
    assert str(path) in msg, f"message does not name the file: {msg}"
    assert "\n" not in msg
    return msg


def test_random_bytes(tmp_path):
    p = tmp_path / "noise.npz"
    p.write_bytes(np.random.default_rng(0).bytes(4096))
    assert load_error(p) == f"{p}: not a readable scene .npz (not a zip archive)"


def test_empty_file_and_plain_npy(tmp_path):
    p = tmp_path / "empty.npz"
    p.write_bytes(b"")
    assert load_error(p) == f"{p}: not a readable scene .npz (not a zip archive)"
    q = tmp_path / "array.npz"
    with open(q, "wb") as f:
        np.save(f, np.arange(5))
    assert load_error(q) == f"{q}: not a readable scene .npz (not a zip archive)"


def test_truncated(saved):
    data = saved.read_bytes()
    saved.write_bytes(data[: len(data) // 2])
    assert "not a readable scene .npz" in load_error(saved)


def test_damaged_member(saved, tmp_path):
    """The zip directory is intact but compressed data is damaged: the error from
    zlib or the CRC check still becomes a SceneError naming the file."""
    data = bytearray(saved.read_bytes())
    with zipfile.ZipFile(saved) as z:
        info = z.getinfo("tri_vertices.npy")
    h = info.header_offset  # local header: name and extra lengths at bytes 26..29
    start = h + 30 + int.from_bytes(data[h + 26:h + 28], "little") + int.from_bytes(data[h + 28:h + 30], "little")
    msgs = []
    for k in range(6):
        d = bytearray(data)
        pos = start + 4 + k * (info.compress_size // 7)
        d[pos:pos + 16] = bytes(16) if k % 2 else b"\xff" * 16
        p = tmp_path / f"damaged{k}.npz"
        p.write_bytes(bytes(d))
        msgs.append(load_error(p))
    assert all("not a readable scene .npz" in m for m in msgs)


def test_missing_array(saved, tmp_path):
    with np.load(saved) as z:
        arrays = {k: z[k] for k in z.files if k != "light_color"}
    p = tmp_path / "missing.npz"
    np.savez_compressed(p, **arrays)
    assert load_error(p) == f"{p}: missing array 'light_color'"
    arrays.pop("camera.lens")
    np.savez_compressed(p, **arrays)
    assert load_error(p) == f"{p}: missing camera field 'lens'"


@pytest.mark.parametrize("version", [0, 2, None])
def test_wrong_format_version(saved, tmp_path, version):
    with np.load(saved) as z:
        arrays = {k: z[k] for k in z.files}
    if version is None:
        del arrays["format_version"]
        shown = -1
    else:
        arrays["format_version"] = np.asarray(version)
        shown = version
    p = tmp_path / "version.npz"
    np.savez_compressed(p, **arrays)
    assert load_error(p) == f"{p}: scene format version {shown}, expected {S.FORMAT_VERSION}"


def test_missing_file(tmp_path):
    p = tmp_path / "nope.npz"
    assert load_error(p) == f"{p}: no such file"


def test_loaded_values_are_validated(saved, tmp_path):
    with np.load(saved) as z:
        arrays = {k: z[k] for k in z.files}
    arrays["tri_vertices"][3, 1, 2] = np.nan
    p = tmp_path / "nan.npz"
    np.savez_compressed(p, **arrays)
    owner = arrays["object_names"][int(arrays["tri_object"][3])] if "object_names" in arrays else None
    with pytest.raises(SceneError, match=re.escape(f"object '{owner}': its vertices hold NaN or infinite values")):
        Scene.load(p)


# ------------------------------------------------------------------- validate
def test_validate_rejects_nan_vertices():
    sc = full_scene()
    sc.tri_vertices[0, 0, 0] = np.nan
    with pytest.raises(SceneError) as e:
        sc.validate()
    assert str(e.value) == f"object '{sc.object_names[sc.tri_object[0]]}': its vertices hold NaN or infinite values " \
                           "(1 triangle)"
    sc = full_scene()
    sc.tri_vertices[-1, 2, 1] = -np.inf
    sc.tri_vertices[-2, 0, 0] = np.nan
    with pytest.raises(SceneError) as e:
        sc.validate()
    assert str(e.value) == f"object '{sc.object_names[sc.tri_object[-2]]}': its vertices hold NaN or infinite " \
                           "values (2 triangles)"


def test_validate_rejects_negative_power_naming_the_light():
    sc = full_scene()
    i = sc.light_names.index("Spot")
    sc.light_color[i, 1] = -1.0
    with pytest.raises(SceneError) as e:
        sc.validate()
    assert str(e.value) == "light 'Spot': negative power"


@pytest.mark.parametrize("ior", [0.0, -1.5, np.nan])
def test_validate_rejects_bad_ior_naming_the_material(ior):
    sc = full_scene()
    sc.mat_ior[sc.mat_names.index("Glass")] = ior
    with pytest.raises(SceneError) as e:
        sc.validate()
    expected = ("material 'Glass': its IOR is NaN or infinite" if np.isnan(ior)
                else "material 'Glass': IOR must be positive")
    assert str(e.value) == expected


@pytest.mark.parametrize("name", ["light_radius", "light_spot_size", "light_spread", "light_angle",
                                  "mat_strength", "mat_roughness", "mat_reflect_color"])
def test_validate_rejects_nan_in_any_float_array(name):
    sc = full_scene()
    getattr(sc, name).flat[0] = np.nan
    with pytest.raises(SceneError) as e:
        sc.validate()
    owner, names = {"light": ("light", sc.light_names), "mat": ("material", sc.mat_names)}[name.split("_")[0]]
    what = {"light_radius": "radius", "light_spot_size": "spot size", "light_spread": "spread", "light_angle": "angle",
            "mat_strength": "strength", "mat_roughness": "roughness", "mat_reflect_color": "reflection colour"}[name]
    assert str(e.value) == f"{owner} '{names[0]}': its {what} is NaN or infinite"


def test_validate_names_the_metal_whose_fresnel_is_wrong():
    """A physical conductor without its index, a metal's Fresnel not finite, a Fresnel model that is none of
    ours: each refused, naming the material."""
    sc = full_scene()
    assert sc.mat_metal.shape == (4, 6) and sc.mat_metal[1, 2] == 1.2
    sc.mat_fresnel[1] = S.FRESNEL_CONDUCTOR
    sc.mat_metal[1] = 0.0
    with pytest.raises(SceneError, match="material 'Gold': a physical conductor needs its index n and extinction k"):
        sc.validate()
    sc.mat_metal[1] = (0.2, 0.9, 1.1, 3.6, 2.6, 2.3)
    sc.validate()
    sc.mat_metal[1, 4] = np.inf
    with pytest.raises(SceneError, match="material 'Gold': its metal's Fresnel .* is not finite"):
        sc.validate()
    sc = full_scene()
    sc.mat_fresnel[2] = 7
    with pytest.raises(SceneError, match="material 'Glass': Fresnel model 7 is none of"):
        sc.validate()
    sc = full_scene()
    sc.mat_fresnel[2] = S.FRESNEL_CONDUCTOR
    sc.mat_metal[2] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    with pytest.raises(SceneError, match="material 'Glass': the physical conductor's Fresnel is a metal's"):
        sc.validate()
    sc = full_scene()  # a glass's Specular Tint (less 1): from black up, never negative
    sc.mat_metal[2] = (-1.0, 0.0, 30.0, 0.0, 0.0, 0.0)
    sc.validate()
    sc.mat_metal[2, 1] = -1.5
    with pytest.raises(SceneError, match="material 'Glass': a glass's Specular Tint must not be negative"):
        sc.validate()


@pytest.mark.parametrize("field,value,message", [
    ("lens", float("nan"), "camera lens must be a positive number, not nan"),
    ("lens", 0.0, "camera lens must be a positive number, not 0.0"),
    ("clip_end", -1.0, "camera clip_end must be a positive number, not -1.0"),
    ("ortho_scale", float("inf"), "camera ortho_scale must be a positive number, not inf"),
    ("shift_x", float("nan"), "camera shift holds NaN or infinite values"),
    ("sensor_fit", "DIAGONAL", "camera sensor fit 'DIAGONAL' not supported (AUTO, HORIZONTAL, VERTICAL)"),
])
def test_validate_rejects_bad_camera(field, value, message):
    sc = full_scene()
    setattr(sc.camera, field, value)
    with pytest.raises(SceneError) as e:
        sc.validate()
    assert str(e.value) == message


def test_validate_rejects_mismatched_shapes():
    sc = full_scene()
    sc.light_radius = sc.light_radius[:-1]
    with pytest.raises(SceneError) as e:
        sc.validate()
    assert str(e.value) == f"scene array 'light_radius' must have one entry per light ({sc.n_lights})"
    sc = full_scene()
    sc.tri_material = sc.tri_material.copy()
    sc.tri_material[5] = len(sc.mat_names)
    with pytest.raises(SceneError, match="triangle material index out of range"):
        sc.validate()


def test_builder_look_at_is_a_rotation():
    m = look_at((1, 2, 3), (0, 0, 0))
    R = m[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(-R[:, 2], -np.array([1, 2, 3]) / math.sqrt(14), atol=1e-15)


def test_geometry_memo_is_exact_and_never_stale():
    """Scene.derived keeps bounds (and a bake's seeders) from validate() on: exactly numpy's
    values, read afresh after an edit in place once the scene is validated again, and ignored
    when the geometry arrays were replaced without validating."""
    sc = scenes.ring_scene()
    sc.object_names = [*sc.object_names, "Empty"]  # an object without triangles
    for name in ("object_caster", "object_receiver", "object_smooth"):
        setattr(sc, name, np.append(getattr(sc, name), False))

    def naive(obj=None):
        v = sc.tri_vertices if obj is None else sc.tri_vertices[sc.tri_object == obj]
        v = v.reshape(-1, 3)
        return v.min(axis=0), v.max(axis=0)

    for validated in (False, True):
        if validated:
            sc.validate()
        for got, want in [(sc.bounds(), naive())] + [(sc.object_bounds(o), naive(o))
                                                     for o in np.unique(sc.tri_object)]:
            assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        lo, hi, has = sc.object_boxes()  # all at once: the same, zeros for an object without triangles
        assert np.array_equal(has, np.isin(np.arange(len(sc.object_names)), sc.tri_object)) and not has.all()
        for o in range(len(sc.object_names)):
            want = naive(o) if has[o] else (np.zeros(3), np.zeros(3))
            assert np.array_equal(lo[o], want[0]) and np.array_equal(hi[o], want[1])
    lo, _ = sc.bounds()
    lo[:] = 99.0  # the caller's copy: the memo keeps its own
    assert np.array_equal(sc.bounds()[0], naive()[0])
    sc.tri_vertices[0, 0, 2] = -123.0  # in place: the memo holds until the next validate()
    assert sc.bounds()[0][2] > -123.0
    sc.validate()
    assert sc.bounds()[0][2] == -123.0 and sc.object_bounds(sc.tri_object[0])[0][2] == -123.0
    sc.tri_vertices = sc.tri_vertices + 1.0  # another array: no memo until validated
    assert np.array_equal(sc.bounds()[0], naive()[0]) and sc.bounds()[0][2] == -122.0
    with pytest.raises(ValueError):  # an object without triangles, as numpy's reduction of nothing
        sc.object_bounds(len(sc.object_names) + 5)


def test_a_bake_builds_each_seeder_once(monkeypatch):
    """Exact count: one Seeder per (chain type, casters) for the whole bake, not one per chunk,
    light and batch."""
    import importlib

    from smbs_addon.walks import seeds as manifold

    bake_mod = importlib.import_module("smbs_addon.baking.passes")  # where the chunk sizes are
    built = []
    init = manifold.Seeder.__init__

    def counting(self, scene, casters, types, method):
        built.append(types)
        init(self, scene, casters, types, method)

    monkeypatch.setattr(manifold.Seeder, "__init__", counting)
    monkeypatch.setattr(bake_mod, "WALK_CHUNK", 500)  # several chunks per batch
    res = bake(scenes.ring_scene(resolution=(40, 30)),
                        BakeSettings(method="sms", spp=2, batches=2, seed=1, guide=False))
    walked = sorted(res.stats["lights"]["Area"]["by_chain"])
    assert sorted(built) == walked and len(walked) >= 1
