"""Blender scene -> Scene arrays (smbs_addon.blender: export_scene and the modules it calls) with tiny
scenes built in bpy: the camera and the world (a constant colour or an Environment Texture)."""
from __future__ import annotations

import math
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from smbs_addon.scene import arrays as S  # noqa: E402
from smbs_addon.core.errors import SceneError  # noqa: E402
from testkit.blend import add_camera, export, mesh_with  # noqa: E402

pytestmark = [pytest.mark.bpy, pytest.mark.usefixtures("empty_bpy")]


def test_camera_fields():
    cam_ob = add_camera(location=(1, -5, 2), lens=35.0, sensor_width=32.0, sensor_height=20.0,
                        sensor_fit="HORIZONTAL", shift_x=0.1, shift_y=-0.05,
                        clip_start=0.5, clip_end=50.0)
    cam_ob.scale = (2, 2, 2)
    r = bpy.context.scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 320, 200, 50
    r.pixel_aspect_x, r.pixel_aspect_y = 1.0, 2.0
    r.use_border, r.use_crop_to_border = True, True
    r.border_min_x, r.border_max_x, r.border_min_y, r.border_max_y = 0.1, 0.6, 0.2, 0.9
    bpy.context.scene.cycles.filter_width = 2.0
    sc, _ = export()
    c = sc.camera
    assert c.type == S.PERSP and c.lens == 35.0 and c.sensor_fit == "HORIZONTAL"
    assert (c.sensor_width, c.sensor_height) == (32.0, 20.0)
    assert np.isclose(c.shift_x, 0.1) and np.isclose(c.shift_y, -0.05)
    assert (c.clip_start, c.clip_end) == (0.5, 50.0)
    assert (c.resolution_x, c.resolution_y, c.resolution_percentage) == (320, 200, 50)
    assert (c.width, c.height) == (160, 100)
    assert (c.pixel_aspect_x, c.pixel_aspect_y) == (1.0, 2.0)
    assert c.use_border and c.use_crop_to_border
    assert np.allclose(c.border, (0.1, 0.6, 0.2, 0.9))
    assert c.filter_width == 2.0
    assert np.allclose(c.matrix_world[:3, 3], [1, -5, 2])
    assert np.allclose(np.linalg.norm(c.matrix_world[:3, :3], axis=0), 1)  # scale removed
    assert np.allclose(-c.matrix_world[:3, 2], [0, 1, 0], atol=1e-6)  # looks along +y


def test_ortho_camera():
    add_camera(type="ORTHO", ortho_scale=2.5)
    sc, _ = export()
    assert sc.camera.type == S.ORTHO and sc.camera.ortho_scale == 2.5


def test_panoramic_camera_is_an_error():
    add_camera(type="PANO", name="Cam")
    with pytest.raises(SceneError, match=r"^camera 'Cam': panoramic cameras are not supported$"):
        export()


def test_no_camera_is_an_error():
    bpy.context.scene.name = "Empty Scene"
    mesh_with(None)
    with pytest.raises(SceneError, match=r"^scene 'Empty Scene' has no camera$"):
        export()


def test_world_background_colour_times_strength():
    add_camera()
    w = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = w
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.5, 0.25, 1.0, 1.0)
    bg.inputs["Strength"].default_value = 2.0
    w.cycles.is_caustics_light = True
    sc, warnings = export()
    assert np.allclose(sc.world_color, [1.0, 0.5, 2.0]) and warnings == []
    # a light of the layer's: radiance from every direction, flagged as the world is
    assert sc.light_names == ["Sky"] and sc.light_type.tolist() == [S.WORLD]
    assert np.allclose(sc.light_color[0], [1.0, 0.5, 2.0]) and sc.light_caustics.tolist() == [True]
    assert sc.light_visibility.size == 0  # every ray sees it
    w.cycles_visibility.glossy = False  # World > Settings > Ray Visibility: what Cycles' own world does
    sc, warnings = export()
    assert sc.light_names == ["Sky"] and warnings == []
    assert sc.light_visibility.tolist() == [S.RAY_ALL & ~S.RAY_GLOSSY]  # no caustic through mirrors
    w.cycles_visibility.transmission = False  # no caustic ray sees it: no light
    sc, warnings = export()
    assert sc.light_names == [] and warnings == [] and np.allclose(sc.world_color, [1.0, 0.5, 2.0])
    w.cycles.is_caustics_light = False
    bg.inputs["Strength"].default_value = 0.0  # black: no light
    sc, _ = export()
    assert sc.light_names == [] and np.allclose(sc.world_color, 0)


def test_textured_world_is_black_with_a_warning():
    add_camera()
    w = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = w
    sky = w.node_tree.nodes.new("ShaderNodeTexSky")
    w.node_tree.links.new(sky.outputs[0], w.node_tree.nodes["Background"].inputs["Color"])
    sc, warnings = export()
    assert np.allclose(sc.world_color, 0) and sc.light_names == []
    assert len(warnings) == 1 and warnings[0].startswith("world 'Sky':")
    from smbs_addon.blender.world import world_unread

    assert world_unread(bpy.context.scene) == "Sky"  # the policy names it (rendered by neither)
    _environment_world(rotation=(0, 0, 30))
    assert world_unread(bpy.context.scene) is None


def _environment_world(projection="EQUIRECTANGULAR", rotation=None, location=(0, 0, 0), vector_type="POINT"):
    w = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = w
    img = bpy.data.images.new("hdr", 8, 4, float_buffer=True)
    px = np.arange(8 * 4 * 4, dtype=np.float32).reshape(4, 8, 4) / 10.0
    img.pixels.foreach_set(px.ravel())
    nt = w.node_tree
    env = nt.nodes.new("ShaderNodeTexEnvironment")
    env.image, env.projection = img, projection
    nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
    nt.nodes["Background"].inputs["Strength"].default_value = 3.0
    if rotation is not None:
        mp, tc = nt.nodes.new("ShaderNodeMapping"), nt.nodes.new("ShaderNodeTexCoord")
        mp.vector_type = vector_type
        mp.inputs["Rotation"].default_value = [math.radians(a) for a in rotation]
        mp.inputs["Location"].default_value = location
        nt.links.new(tc.outputs["Generated"], mp.inputs["Vector"])
        nt.links.new(mp.outputs["Vector"], env.inputs["Vector"])
    return px[..., :3]


def test_an_environment_texture_is_the_worlds_map():
    """An equirectangular Environment Texture on the Background's Color is the world light's map
    (Scene.world_map: the linear pixels, rows from the bottom up, as bpy holds them), its Strength
    the light's colour, a Mapping node's turn the lookup's (Texture type: the inverse)."""
    add_camera()
    px = _environment_world(rotation=(10, 20, 30))
    sc, warnings = export()
    assert warnings == [] and sc.light_names == ["Sky"] and sc.light_type.tolist() == [S.WORLD]
    assert np.array_equal(sc.world_map, px) and np.allclose(sc.light_color[0], 3.0)
    from mathutils import Euler
    R = np.array(Euler([math.radians(a) for a in (10, 20, 30)]).to_matrix())
    assert np.allclose(sc.world_map_rotation, R)
    _environment_world(rotation=(10, 20, 30), vector_type="TEXTURE")
    assert np.allclose(export()[0].world_map_rotation, R.T)
    _environment_world()
    sc, warnings = export()
    assert warnings == [] and np.allclose(sc.world_map_rotation, np.eye(3))


def test_a_large_map_is_averaged_down():
    """An HDRI wider than WORLD_MAP_WIDTH is averaged over blocks (uneven where the widths do not
    divide): every block the mean of its pixels, the map's mean kept."""
    from smbs_addon.blender.world import _averaged_down

    rng = np.random.default_rng(3)
    img = rng.random((10, 20, 3)).astype(np.float32)
    small = _averaged_down(img, 4)
    assert small.shape == (2, 4, 3) and small.dtype == np.float32
    assert np.allclose(small[0, 0], img[:5, :5].mean(axis=(0, 1)), atol=1e-6)
    assert np.allclose(small.mean(axis=(0, 1)), img.mean(axis=(0, 1)), atol=1e-6)
    odd = _averaged_down(img, 3)  # columns 0-7, 7-13, 13-20
    assert odd.shape == (2, 3, 3) and np.allclose(odd[1, 1], img[5:, 7:13].mean(axis=(0, 1)), atol=1e-6)
    assert _averaged_down(img, 20) is img


def test_an_hdris_negative_or_nan_pixels_are_black_and_said():
    """A few negative or NaN pixels (left by an HDRI's processing) would make the scene invalid:
    they are taken as black, the rest kept, and the warning names the world and the image."""
    add_camera()
    px = _environment_world()
    img = bpy.data.images["hdr"]
    bad = px.copy()
    bad[1, 2, 0], bad[3, 5, 1] = -0.5, float("nan")
    img.pixels.foreach_set(np.concatenate([bad, np.ones((4, 8, 1), np.float32)], axis=2).ravel())
    sc, warnings = export()
    assert sc.world_map[1, 2, 0] == 0 and sc.world_map[3, 5, 1] == 0
    keep = np.ones(px.shape, bool)
    keep[1, 2, 0] = keep[3, 5, 1] = False
    assert np.array_equal(sc.world_map[keep], px[keep])
    assert warnings == ["world 'Sky': image 'hdr': 2 pixels negative or not a number, taken as black"], warnings


@pytest.mark.parametrize("kw, why", [
    (dict(projection="MIRROR_BALL"), "its mirror ball projection is not supported"),
    (dict(rotation=(0, 0, 45), location=(0, 0, 1)), "only a turn (no Location"),
])
def test_an_environment_the_layer_cannot_read_is_black_with_a_warning(kw, why):
    add_camera()
    _environment_world(**kw)
    sc, warnings = export()
    assert sc.light_names == [] and sc.world_map.size == 0
    assert len(warnings) == 1 and warnings[0].startswith("world 'Sky'") and why in warnings[0], warnings
