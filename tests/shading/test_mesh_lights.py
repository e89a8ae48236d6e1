"""Mesh lights: an object's triangles of an Emission shader shine as a light (Scene.tri_light,
S.MESH): radiance Color x Strength from both sides of every triangle, as Cycles' emissive closure
shines (testing-against-cycles.md: S is radiance). Judged against Cycles in the conformance suite
(mesh_light_ball, mesh_light_mirror); here: the builder's lights, validation, the photons' flux
against the analytic one, and bakes of a panel against an area light of the same radiance."""
from __future__ import annotations

import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.shading import lights
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.core.errors import SceneError
from smbs_addon.shading.light_samples import sample_light
from smbs_addon.shading.light_samples import light_end_at_solution


def _panel_scene(light="mesh", facing=-1.0, strength=60.0, size=0.8, res=(48, 36)):
    """A glass ball over a floor under a square light 3 m up: a mesh panel of an emitter material whose
    normal points down (facing -1, towards the ball) or up (facing 1: the ball sees its back), or of a
    diffuse material with that emission (light "glow", a Principled BSDF's Emission), or an area light
    of the same radiance (power L pi A) facing down."""
    b = SceneBuilder("panel")
    floor = b.material("Floor", "diffuse", color=(0.8, 0.8, 0.8))
    glass = b.material("Glass", "dielectric", color=(1.0, 1.0, 1.0), ior=1.5)
    b.plane("Floor", (0, 0, 0), 6, floor, receiver=True)
    b.uv_sphere("Ball", (0, 0, 0.9), 0.5, glass, segments=48, rings=24, caster=True)
    color = (1.0, 0.9, 0.75)
    if light in ("mesh", "glow"):
        lamp = b.material("Glow", "emitter", color=color, strength=strength) if light == "mesh" else \
            b.material("Glow", "diffuse", color=(0.8, 0.8, 0.8), emission=np.multiply(color, strength))
        b.plane("Panel", (0.3, -0.2, 3.0), size, lamp, normal=(0, 0, facing), receiver=light == "glow")
    else:
        b.light("Panel", "AREA", location=(0.3, -0.2, 3.0), target=(0.3, -0.2, 0.0),
                power=strength * math.pi * size * size, color=color, size=size)
    b.set_camera((0, -3.6, 2.8), (0, 0, 0.2), lens=40, resolution_x=res[0], resolution_y=res[1])
    return b.build()


# ------------------------------------------------------------------------------- the builder
def test_an_emitter_object_becomes_a_mesh_light_of_its_radiance():
    sc = _panel_scene()
    assert sc.light_names == ["Panel"] and sc.light_type.tolist() == [S.MESH]
    assert np.allclose(sc.light_color[0], np.array([1.0, 0.9, 0.75]) * 60.0)  # radiance, W/m^2/sr
    panel = sc.object_names.index("Panel")
    assert np.array_equal(sc.tri_light >= 0, sc.tri_object == panel)
    idx, tv, ng, cdf, area = sc.mesh_light(0)
    assert len(idx) == 2 and math.isclose(area, 0.64, rel_tol=1e-12)
    assert np.allclose(np.abs(ng[:, 2]), 1.0)
    assert np.allclose(sc.light_matrix[0][:3, 3], [0.3, -0.2, 3.0])  # its centroid
    assert math.isclose(sc.light_radius[0], 0.4 * math.sqrt(2), rel_tol=1e-9)


def test_dark_emitters_are_no_light_and_each_glowing_material_is_one():
    b = SceneBuilder("two")
    dark = b.material("Dark", "emitter", color=(1, 1, 1), strength=0.0)
    warm = b.material("Warm", "emitter", color=(1, 0.5, 0.2), strength=3.0)
    cold = b.material("Cold", "emitter", color=(0.2, 0.5, 1), strength=2.0)
    b.mesh("Sign", [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]],
           [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]], warm, face_materials=[warm, warm, cold, dark],
           visibility=S.RAY_ALL & ~S.RAY_GLOSSY)
    b.plane("Off", (0, 0, 2), 1.0, dark)
    sc = b.build()
    assert sc.light_names == ["Sign/Warm", "Sign/Cold"]
    assert sc.tri_light.tolist() == [0, 0, 1, -1, -1, -1]
    assert np.allclose(sc.light_color, [[3.0, 1.5, 0.6], [0.4, 1.0, 2.0]])
    assert sc.light_visibility.tolist() == [S.RAY_ALL & ~S.RAY_GLOSSY] * 2  # the object's Ray Visibility
    assert not sc.light_seen_by(0, S.RAY_GLOSSY) and sc.light_seen_by(1, S.RAY_TRANSMISSION)
    assert SceneBuilder("none").build().tri_light.shape == (0,)


def test_a_scene_file_keeps_its_mesh_lights(tmp_path):
    sc = _panel_scene(light="glow")
    assert np.allclose(sc.mat_emission, [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [60.0, 54.0, 45.0]])
    assert np.allclose(sc.light_color, [[60.0, 54.0, 45.0]])
    sc.save(tmp_path / "s.npz")
    back = S.Scene.load(tmp_path / "s.npz")
    assert np.array_equal(back.tri_light, sc.tri_light) and back.light_type.tolist() == [S.MESH]
    assert np.array_equal(back.mat_emission, sc.mat_emission)


def test_validation_names_the_light():
    sc = _panel_scene()
    sc.tri_light = np.full(sc.n_tris, -1, np.int32)
    with pytest.raises(SceneError, match="light 'Panel': a mesh light without triangles"):
        sc.validate()
    sc = _panel_scene(light="area")
    sc.tri_light = np.zeros(sc.n_tris, np.int32)
    with pytest.raises(SceneError, match="light 'Panel': triangles shine as it, but it is not a mesh light"):
        sc.validate()
    sc.tri_light = np.zeros(3, np.int32)
    with pytest.raises(SceneError, match="'tri_light' must have one entry per triangle"):
        sc.validate()
    sc = _panel_scene(light="glow")
    sc.mat_emission[2, 1] = -1.0
    with pytest.raises(SceneError, match="material 'Glow': emission must be finite"):
        sc.validate()


# ------------------------------------------------------------------------------- radiometry
@pytest.mark.parametrize("facing", [-1.0, 1.0])
def test_photon_flux_towards_a_small_sphere_is_the_analytic_one(facing):
    """A 0.1 m square panel of radiance L facing a sphere of radius 0.1 at 10 m along its normal
    (or facing away: both sides shine) sends it L A pi R^2 / h^2 (to 1e-4: the cone's cosines);
    every photon carries nearly the same weight."""
    b = SceneBuilder("flux")
    lamp = b.material("Glow", "emitter", color=(1.0, 0.5, 0.25), strength=40.0)
    b.plane("Panel", (0, 0, 10.0), 0.1, lamp, normal=(0, 0, facing))
    sc = b.build()
    targets = np.array([[0.0, 0.0, 0.0, 0.1]])
    ph = lights.emit(sc, 0, targets, 20000, np.random.default_rng(3))
    expect = 40.0 * np.array([1.0, 0.5, 0.25]) * 0.01 * math.pi * 0.01 / 100.0
    assert np.allclose(ph.w.sum(axis=0), expect, rtol=2e-4)
    assert np.all(ph.o[:, 2] < 10.0)  # off the surface, on the side the photons leave
    assert np.all(ph.d[:, 2] < 0)


def test_the_walks_light_end_is_the_radiance_over_the_area_density():
    sc = _panel_scene(facing=1.0)
    light = sample_light(sc, 0, 1000, np.random.default_rng(1))
    assert np.allclose(light.y[:, 2], 3.0) and np.all(np.abs(light.y[:, :2] - [0.3, -0.2]) <= 0.4 + 1e-12)
    xk = np.tile([0.0, 0.0, 1.4], (1000, 1))
    end, e = light_end_at_solution(sc, 0, light, xk)
    assert np.allclose(np.abs(np.cross(end.ys, end.yt)[:, 2]), 1.0)
    assert np.allclose(e, sc.light_color[0] * 0.64)  # L / (1 / A), the back side too


def _caustic(sc, method, spp, seed):
    """The caustic's luminance summed over the image, per batch: (mean, standard error)."""
    r = bake(sc, BakeSettings(method=method, spp=spp, seed=seed))
    per = r.batch_luminance.reshape(len(r.batch_luminance), -1).sum(axis=1)
    return per.mean(), per.std(ddof=1) / math.sqrt(len(per))


@pytest.mark.parametrize("method,facing,light", [("reference", 1.0, "mesh"), ("smbs", -1.0, "mesh"),
                                                ("sms", 1.0, "mesh"), ("smbs", 1.0, "glow")])
def test_a_mesh_panel_casts_the_caustic_of_an_area_light_of_its_radiance(method, facing, light):
    """The ball's caustic under the panel (either side towards it; an emitter, or a diffuse receiver that
    emits) equals the one under an area light of the same radiance and size, whose estimate is
    independent (4 standard errors of the difference; each ~1.5% at 32 samples per pixel)."""
    m, m_se = _caustic(_panel_scene(light=light, facing=facing), method, 32, 5)
    a, a_se = _caustic(_panel_scene(light="area"), method, 32, 6)
    assert m > 0 and a > 0
    assert abs(m - a) <= 4.0 * math.hypot(m_se, a_se), (m, m_se, a, a_se)


def _bulb_over_mirror(area=None):
    """A standing flat mirror beside a glowing ball of radius 0.2 (an emitter material of Strength 250 on
    a 32 x 16 UV sphere), or with area (the ball's), a point light of radius 0.2 of its power (L pi A)."""
    b = SceneBuilder("bulb")
    floor = b.material("Floor", "diffuse", color=(0.8, 0.8, 0.8))
    mirror = b.material("Mirror", "conductor", color=(0.9, 0.9, 0.9))
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (1.2, 0, 0.55), (1.0, 1.6), mirror, normal=(-1, 0, 0), caster=True)
    if area is None:
        lamp = b.material("Lamp", "emitter", color=(1, 1, 1), strength=250.0)
        b.uv_sphere("Bulb", (0.5, 0, 1.4), 0.2, lamp, segments=32, rings=16)
    else:
        b.light("Bulb", "POINT", location=(0.5, 0, 1.4), power=250.0 * math.pi * area, radius=0.2)
    b.set_camera((-2.6, -1.3, 1.7), (1.2, 0.1, 0.45), lens=35, resolution_x=48, resolution_y=36)
    return b.build()


def test_a_glowing_ball_lights_a_mirror_as_a_sphere_light_of_its_power():
    """The walks' shadow ray to a point on a closed mesh light must not meet the light itself: it runs
    eps off the line to the point, and at normal incidence dist - eps reached the triangle's plane
    (lights.shadow_tmax). SMS under the ball against SMS under a point light of its power and radius
    (independent samples; 4 standard errors of the difference, each ~1%): 0.67 before."""
    ball = _bulb_over_mirror()
    m, m_se = _caustic(ball, "sms", 16, 3)
    p, p_se = _caustic(_bulb_over_mirror(area=ball.mesh_light(0)[4]), "sms", 16, 4)
    assert abs(m - p) <= 4.0 * math.hypot(m_se, p_se), (m, m_se, p, p_se)


def test_a_mesh_light_does_not_make_auto_honour_the_lamps_flags():
    """Cycles has no Shadow Caustics flag for a mesh light: it is always baked, and it does not count as
    a flagged light, so AUTO keeps an unflagged lamp beside it (and honours the lamps' flags once one
    lamp is flagged)."""
    from smbs_addon.baking.plan import make_plan

    def plan_of(flag_lamp):
        b = SceneBuilder("flags")
        floor = b.material("Floor", "diffuse")
        glass = b.material("Glass", "dielectric", ior=1.5)
        lamp = b.material("Glow", "emitter", color=(1, 1, 1), strength=10.0)
        b.plane("Floor", (0, 0, 0), 6, floor, receiver=True)
        b.uv_sphere("Ball", (0, 0, 0.9), 0.5, glass, segments=16, rings=8, caster=True)
        b.plane("Panel", (0.3, -0.2, 3.0), 0.8, lamp)
        b.light("Bulb", "POINT", location=(1, 0, 3), power=100.0, radius=0.1, caustics=False)
        if flag_lamp:
            b.light("Key", "POINT", location=(-1, 0, 3), power=100.0, radius=0.1, caustics=True)
        b.set_camera((0, -3.6, 2.8), (0, 0, 0.2), resolution_x=32, resolution_y=24)
        return make_plan(b.build())

    assert sorted(lp.name for lp in plan_of(False).lights) == ["Bulb", "Panel"]
    plan = plan_of(True)
    assert sorted(lp.name for lp in plan.lights) == ["Key", "Panel"]
    assert ("light", "Bulb", "not flagged 'Shadow Caustics'") in plan.skipped


def _under_the_sky(dome):
    """The glass ball over a floor under a sky of radiance 1: a world (S.WORLD), or an emitter dome of radius 40
    around everything (a mesh light the camera is inside)."""
    b = SceneBuilder("sky")
    floor = b.material("Floor", "diffuse")
    glass = b.material("Glass", "dielectric", ior=1.5)
    b.plane("Floor", (0, 0, 0), 6, floor, receiver=True)
    b.uv_sphere("Ball", (0, 0, 0.9), 0.5, glass, segments=48, rings=24, caster=True)
    if dome:
        b.uv_sphere("Dome", (0, 0, 0), 40.0, b.material("Sky", "emitter", color=(1, 1, 1), strength=1.0),
                    segments=64, rings=32)
    else:
        b.world((1.0, 1.0, 1.0))
    b.set_camera((0, -3.6, 2.8), (0, 0, 0.2), lens=40, resolution_x=48, resolution_y=36)
    return b.build()


def test_an_emitter_dome_casts_the_caustic_of_a_world_of_its_radiance():
    """A mesh light the whole scene sits in (the camera too) against the world light, each baked by the other
    estimator (SMBS under the dome, 64 spp, the light tracer under the world): within 4 standard errors of the
    difference (each ~2.5%)."""
    m, m_se = _caustic(_under_the_sky(True), "smbs", 64, 7)
    w, w_se = _caustic(_under_the_sky(False), "reference", 64, 8)
    assert abs(m - w) <= 4.0 * math.hypot(m_se, w_se), (m, m_se, w, w_se)
