"""Rough mirrors and glass (rough.py, optics.scatter1): the sampled scatter against the microfacet
BSDF written out independently (Walter et al. 2007 with Smith's height-correlated shadowing, in
Cycles' conventions), integrated over cones of directions by uniform sampling."""
from __future__ import annotations

import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.shading import energy, fresnel, optics, microfacet as rough
from smbs_addon.scene import arrays as S
from smbs_addon.scene.builder import SceneBuilder
from testkit import scenes

N = 400_000


def _scene(kind, roughness, color=(1.0, 1.0, 1.0), ior=1.5, distribution=rough.MULTI_GGX, fresnel=S.FRESNEL_NONE):
    b = SceneBuilder("rough")
    floor = b.material("floor", "diffuse")
    m = b.material("caster", kind, color=color, ior=ior, roughness=roughness, distribution=distribution,
                   fresnel=fresnel)
    b.plane("Floor", (0, 0, 0), 4, floor, receiver=True)
    b.plane("Caster", (0, 0, 1), 1, m, caster=True)
    b.light("Bulb", "POINT", location=(0, 0, 3), power=10.0)
    b.set_camera((0, -3, 2), (0, 0, 0), resolution_x=8, resolution_y=8)
    return b.build(), m


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _lam(c, a2):
    return 0.5 * (np.sqrt(1.0 + a2 * np.maximum(1.0 / (c * c) - 1.0, 0.0)) - 1.0)


def _ggx_d(cos_h, a2):
    return a2 / (math.pi * (1.0 + (a2 - 1.0) * cos_h * cos_h) ** 2)


def bsdf_cos(wi, wo, alpha, ior, glass, R=None):
    """f(wi, wo) |wo.n| of a GGX surface of normal +z (wi.z > 0: the eye's side), Cycles' form: no
    eta^2 radiance factor; ior: the far side's index over wi's side's. R: a mirror's reflectance
    (3,), else the dielectric Fresnel."""
    a2 = alpha * alpha
    ci, co = wi[:, 2], wo[:, 2]
    out = np.zeros((len(wi), 3))
    refl = co > 0
    h = _unit(wi + wo)
    ch = np.abs(h[:, 2])
    g2 = 1.0 / (1.0 + _lam(ci, a2) + _lam(co, a2))
    F = fresnel.fresnel_dielectric((wi * h).sum(1) * np.sign(h[:, 2]), ior) if glass else None
    fr = (F[:, None] if glass else np.broadcast_to(R, (len(wi), 3))) * (_ggx_d(ch, a2) * g2 / (4.0 * ci))[:, None]
    out[refl] = fr[refl]
    if glass:
        ht = -(ior * wo + wi)
        ln = np.linalg.norm(ht, axis=1)
        ht = ht / ln[:, None] * np.sign(ht[:, 2])[:, None]
        c_hi, c_ho = (wi * ht).sum(1), (wo * ht).sum(1)
        ok = (~refl) & (c_hi > 0) & (c_ho < 0)
        Ft = fresnel.fresnel_dielectric(c_hi, ior)
        ft = (1.0 - Ft) * _ggx_d(ht[:, 2], a2) * g2 * np.abs(c_hi * c_ho) * ior * ior / (ci * ln * ln)
        out[ok] = ft[ok][:, None]
    return out


def _cone(axis, half, n, rng):
    """n uniform directions in the cone of half-angle half about axis, and its solid angle."""
    z = 1.0 - rng.random(n) * (1.0 - math.cos(half))
    phi = 2 * math.pi * rng.random(n)
    r = np.sqrt(1.0 - z * z)
    local = np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)
    a = _unit(np.asarray(axis, float))
    t = _unit(np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0]))
    bt = np.cross(a, t)
    return local @ np.stack([t, bt, a]), 2 * math.pi * (1.0 - math.cos(half))


def _scattered(scene, m, w_in, rng, adjoint=False):
    u = rng.random((N, 3))
    w = np.broadcast_to(w_in, (N, 3)).copy()
    n = np.broadcast_to([0.0, 0.0, 1.0], (N, 3)).copy()
    d, b, keep = optics.scatter_rows(u, w, n, n, np.full(N, m), np.full(N, int(scene.mat_kind[m])),
                                     optics.materials(scene), np.ones((N, 3)), False, adjoint)
    return d, b


def _compare(scene, m, w_in, axis, half, expect_fn, rng, adjoint=False):
    d, b = _scattered(scene, m, w_in, rng, adjoint)
    a = _unit(np.asarray(axis, float))
    inside = (d @ a) > math.cos(half)
    contrib = np.zeros((N, 3))  # the lanes scatter_rows dropped carry nothing
    contrib[: inside.sum()] = b[inside]
    mean, se = contrib.mean(0), contrib.std(0) / math.sqrt(N)
    dirs, omega = _cone(axis, half, N, rng)
    f = expect_fn(dirs) * omega
    ref, ref_se = f.mean(0), f.std(0) / math.sqrt(N)
    assert ref.max() > 1e-3, "the cone catches some of the lobe"
    tol = 4.5 * np.sqrt(se**2 + ref_se**2) + 2e-3 * ref
    assert np.all(np.abs(mean - ref) < tol), (mean, ref, tol)
    return mean, ref


@pytest.mark.parametrize("side", ["outside", "inside"])
def test_rough_glass_matches_the_bsdf(side):
    """GGX (single scattering) glass of alpha 0.16: both lobes, from outside and from inside (where
    the microfacets reflect totally past the critical angle), in cones about the mirror and the
    refracted directions and off them."""
    rng = np.random.default_rng(3)
    scene, m = _scene("dielectric", 0.4, distribution=rough.GGX)
    alpha, ior = 0.16, 1.5
    wi = _unit(np.array([0.45, 0.1, 0.9]))
    sign = 1.0 if side == "outside" else -1.0
    w_in = wi * np.array([1, 1, sign])  # the geometric normal is +z: inside, the path arrives from below
    rel = ior if side == "outside" else 1.0 / ior

    def expect(dirs):
        flip = np.array([1, 1, sign])  # into the frame where wi is above
        return bsdf_cos(np.broadcast_to(wi, dirs.shape), dirs * flip, alpha, rel, True)

    refl_axis = np.array([-wi[0], -wi[1], wi[2]]) * np.array([1, 1, sign])
    t, ok = optics.refract(wi[None], np.array([[0, 0, 1.0]]), ior if side == "outside" else 1.0 / ior)
    assert ok[0]
    refr_axis = t[0] * np.array([1, 1, sign])
    for axis, half in ((refl_axis, 0.35), (refr_axis, 0.3), (refr_axis + 0.3 * np.array([1, 0, 0]), 0.25)):
        _compare(scene, m, w_in, axis, half, expect, rng)


def test_rough_mirror_matches_the_bsdf():
    """A coloured Glossy BSDF (no Fresnel) of Roughness 0.5, GGX: reflection into cones at and off the
    mirror direction, at a slant where the shadowing matters."""
    rng = np.random.default_rng(4)
    color = np.array([0.9, 0.6, 0.3])
    scene, m = _scene("conductor", 0.5, color=color, distribution=rough.GGX)
    wi = _unit(np.array([0.8, 0.0, 0.35]))
    expect = lambda dirs: bsdf_cos(np.broadcast_to(wi, dirs.shape), dirs, 0.25, 1.5, False, R=color)  # noqa: E731
    for axis, half in ((np.array([-0.8, 0, 0.35]), 0.4), (np.array([-0.3, 0.2, 0.9]), 0.3)):
        _compare(scene, m, wi, axis, half, expect, rng)


def test_photons_sample_the_same_bsdf():
    """adjoint (a photon arriving along -w_in): its weight into a cone is the BSDF with the eye's
    direction in the cone, f(d, w_in) |w_in.n| ... integrated over d: for a reflection the same
    form, the eye and light swapped (and for a mirror exactly symmetric)."""
    rng = np.random.default_rng(5)
    color = np.array([0.7, 0.7, 0.7])
    scene, m = _scene("conductor", 0.45, color=color, distribution=rough.GGX)
    wl = _unit(np.array([0.5, -0.2, 0.6]))
    alpha = 0.45**2

    def expect(dirs):  # sum over eye directions d of f(d, wl) |wl.n| ... times |d.n| / |wl.n|
        return bsdf_cos(dirs, np.broadcast_to(wl, dirs.shape), alpha, 1.5, False, R=color) \
            * (dirs[:, 2] / wl[2])[:, None]

    _compare(scene, m, wl, np.array([-0.5, 0.2, 0.6]), 0.4, expect, rng, adjoint=True)


def test_multiscatter_glass_keeps_all_the_light():
    """Multiscatter GGX white glass: Cycles scales the lobes by 1 / E, so what a path keeps averages
    to 1 at every incidence (to the table's interpolation), where GGX alone keeps E < 1."""
    rng = np.random.default_rng(6)
    for side in (1.0, -1.0):
        for mu in (0.95, 0.6, 0.3):
            w = np.array([math.sqrt(1 - mu * mu), 0.0, side * mu])
            multi, m = _scene("dielectric", 0.6, distribution=rough.MULTI_GGX)
            single, _ = _scene("dielectric", 0.6, distribution=rough.GGX)
            e = energy.glass_albedo(np.array([mu]), 0.36, 1.5 if side > 0 else 1 / 1.5)[0]
            _, b1 = _scattered(single, m, w, rng)
            _, bm = _scattered(multi, m, w, rng)
            s1, sm = b1[:, 0].sum() / N, bm[:, 0].sum() / N
            assert 0.5 < e < 0.995
            assert abs(s1 - e) < 5 * b1[:, 0].std() / math.sqrt(N) + 2e-3, (side, mu, s1, e)
            assert abs(sm - 1.0) < 5 * bm[:, 0].std() / math.sqrt(N) + 5e-3, (side, mu, sm)


def test_multiscatter_mirror_gain_is_cycles_form():
    """A coloured Multiscatter GGX mirror: the factor is 1 + F_ms (1 - E) / E per channel, F_ms from
    the colour (F_ss) and E's hemispherical mean: a white one keeps all the light."""
    rng = np.random.default_rng(7)
    white, m = _scene("conductor", 0.7, color=(1.0, 1.0, 1.0))
    w = np.array([0.6, 0.0, 0.8])
    _, b = _scattered(white, m, w, rng)
    assert abs(b[:, 0].sum() / N - 1.0) < 5e-3
    tinted, m = _scene("conductor", 0.7, color=(0.9, 0.5, 0.2))
    table = energy.energy_tables(tinted)[m, 0]
    mu = np.linspace(0, 1, table.shape[0])
    E = energy.visible_albedo(mu, 0.49)
    e_avg = 2 * (getattr(np, "trapezoid", None) or np.trapz)(E * mu, mu)
    for c, fss in enumerate((0.9, 0.5, 0.2)):
        fms = fss * e_avg / (1 - fss * (1 - e_avg))
        np.testing.assert_allclose(table[:, c], 1 + fms * (1 - np.maximum(E, 1e-4)) / np.maximum(E, 1e-4), rtol=2e-3)
    assert np.all(table[:, 0] > table[:, 2])  # the brighter channel gains more: saturation


def test_multiscatter_glass_gain_takes_its_colour():
    """A coloured Multiscatter GGX glass: Cycles takes its transmission tint for F_ss (white: 1 / E), so a
    blue-poor glass gets back less of the blue its microfacets lose (rough_tinted_glass, light tracer 1024
    spp, red / green / blue against Cycles: 1.008 / 1.047 / 1.085 with F_ss = 1, 0.994 / 0.996 / 0.998 now);
    a glass without transmission tint takes its reflection tint times the mean Fresnel."""
    mu = np.linspace(0, 1, 65)
    colour = (0.9, 0.6, 0.3)
    for side, eta in ((0, 1.5), (1, 1 / 1.5)):
        E = np.maximum(energy.glass_albedo(mu, 0.25, eta), 1e-4)
        e_avg = 2 * (getattr(np, "trapezoid", None) or np.trapz)(E * mu, mu)
        tinted, m = _scene("dielectric", 0.5, color=colour)
        table = energy.energy_tables(tinted)[m, side]
        for c, fss in enumerate(colour + (1.0,)):
            fms = fss * e_avg / (1 - fss * (1 - e_avg))
            want = 1 + fms * (1 - E) / E
            got = table[:, c] if c < 3 else energy.energy_tables(_scene("dielectric", 0.5)[0])[m, side, :, 0]
            np.testing.assert_allclose(got, want, rtol=3e-3, err_msg=f"side {side} channel {c}")
        np.testing.assert_allclose(want, 1 / E, rtol=1e-9)  # white: F_ms = 1
    black, m = _scene("dielectric", 0.5, color=(0.0, 0.0, 0.0))
    f_avg = 2 * (getattr(np, "trapezoid", None) or np.trapz)(fresnel.fresnel_dielectric(mu, 1.5) * mu, mu)
    assert 0.08 < f_avg < 0.1
    E = np.maximum(energy.glass_albedo(mu, 0.25, 1.5), 1e-4)
    e_avg = 2 * (getattr(np, "trapezoid", None) or np.trapz)(E * mu, mu)
    fms = f_avg * e_avg / (1 - f_avg * (1 - e_avg))
    np.testing.assert_allclose(energy.energy_tables(black)[m, 0, :, 1], 1 + fms * (1 - E) / E, rtol=3e-3)
    # under a Specular Tint (Principled glass) the mean maps as F does (Cycles' generalized Schlick F_ss):
    # f0 x tint + (1 - f0 x tint) (f_avg - f0) / (1 - f0), f0 = 0.04; a white channel keeps f_avg
    import dataclasses
    tint = np.array([3.0, 1.0, 0.0])
    metal = np.zeros((len(black.mat_kind), 6))
    metal[m, :3] = tint - 1.0
    f0t = 0.04 * tint
    f_tint = f0t + (1 - f0t) * (f_avg - 0.04) / 0.96
    fms = f_tint * e_avg / (1 - f_tint * (1 - e_avg))
    np.testing.assert_allclose(energy.energy_tables(dataclasses.replace(black, mat_metal=metal))[m, 0],
                               1 + fms[None, :] * ((1 - E) / E)[:, None], rtol=3e-3)


def test_smooth_below_the_threshold():
    """alpha^2 at or under 1e-7 (rough.SINGULAR_ALPHA2; Cycles' own threshold is 2e-10) is baked as a perfect
    mirror: the same directions and weights as Roughness 0, bit for bit."""
    rng = np.random.default_rng(8)
    w = _unit(np.array([0.3, 0.2, 0.9]))
    a, m = _scene("dielectric", 0.0)
    b_, _ = _scene("dielectric", 1e-7 ** 0.25 * 0.999)
    assert rough.alphas(b_)[m] == 0
    u = rng.random((1000, 3))
    args = lambda sc: (u, np.tile(w, (1000, 1)), np.tile([0, 0, 1.0], (1000, 1)), np.tile([0, 0, 1.0], (1000, 1)),  # noqa: E731
                       np.full(1000, m), np.full(1000, S.DIELECTRIC), optics.materials(sc), np.ones((1000, 3)),
                       False, False)
    for x, y in zip(optics.scatter_rows(*args(a)), optics.scatter_rows(*args(b_))):
        assert np.array_equal(x, y)


def test_grazing_and_degenerate_stay_finite():
    """Grazing incidence, a normal at right angles to the path, roughness 1: no NaN, no infinity."""
    rng = np.random.default_rng(9)
    for kind in ("dielectric", "conductor"):
        sc, m = _scene(kind, 1.0)
        for w in ([1.0, 0, 1e-9], [1.0, 0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], [0.999, 0, -0.04]):
            d, b = _scattered(sc, m, _unit(np.array(w)), rng)
            assert np.all(np.isfinite(d)) and np.all(np.isfinite(b)) and np.all(b >= 0)


def _rough_ball(roughness=0.3):
    sc = scenes.glass_sphere_scene(resolution=(48, 36))
    sc.mat_roughness = np.where(sc.mat_kind == S.DIELECTRIC, roughness, sc.mat_roughness)
    return sc


def _energy(res):
    """The image's sum and its standard error from the batches' spread."""
    per_batch = res.batch_luminance.reshape(len(res.batch_luminance), -1).sum(axis=1)
    return per_batch.mean(), per_batch.std(ddof=1) / math.sqrt(len(per_batch))


@pytest.mark.parametrize("method", ["smbs", "mnee"])
def test_walks_leave_a_rough_glass_to_the_photons(method):
    """No walk solves a rough surface's paths: the walks skip the rough ball (none is walked) and every
    path through it goes to the photons, the user's hand-off setting or MNEE's none notwithstanding;
    the caustic is the light tracer's within 4 sigma (both photons, independent samples), and the plan
    says so."""
    sc = _rough_ball()
    ref = bake(sc, BakeSettings(method="reference", spp=16, batches=8, seed=2))
    res = bake(sc, BakeSettings(method=method, spp=4, batches=8, seed=3, handoff=0.0))
    st = res.stats["lights"]["Area"]
    assert st["walks"] == 0 and res.stats["chain_types"] == []
    assert st["handoff"]["handoff_paths"] > 1000
    assert any(n.startswith("Ball: rough, so its caustic comes from the photons") for n in res.stats["plan"]["notes"])
    (e_ref, s_ref), (e, s) = _energy(ref), _energy(res)
    assert e_ref > 0 and abs(e - e_ref) < 4 * math.hypot(s, s_ref), (e, e_ref, s, s_ref)


def test_rough_and_smooth_casters_split_the_paths():
    """A smooth mirror beside a rough glass ball: the walks take the mirror's paths (walks > 0, chain
    type R on the mirror only), the photons the ball's, and together they make the light tracer's
    caustic within 4 sigma."""
    b = SceneBuilder("split")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=1.5, roughness=0.35)
    mirror = b.material("mirror", "conductor", color=(0.9,) * 3)
    b.plane("Floor", (0, 0, 0), 10, floor)
    b.uv_sphere("Ball", (-0.6, 0, 1.0), 0.4, glass, segments=48, rings=24)
    b.plane("Mirror", (1.2, 0, 0.8), 1.0, mirror, normal=np.array([-1.0, 0, 0.3]) / math.hypot(1, 0.3))
    b.light("Area", "AREA", location=(0.0, 0.2, 4.0), target=(0.0, 0.2, 0), power=600.0, size=0.6)
    b.set_camera((0, -3.0, 3.0), (0, 0, 0.3), lens=35, resolution_x=48, resolution_y=36)
    sc = b.build()
    assert rough.walk_casters(sc, np.ones(len(sc.object_names), bool)).tolist() == [True, False, True]
    ref = bake(sc, BakeSettings(method="reference", spp=32, batches=8, seed=2))
    res = bake(sc, BakeSettings(method="sms", spp=4, batches=8, seed=3))
    st = res.stats["lights"]["Area"]
    assert st["walks"] > 0 and st["successes"] > 0 and st["handoff"]["handoff_paths"] > 100
    (e_ref, s_ref), (e, s) = _energy(ref), _energy(res)
    assert abs(e - e_ref) < 4 * math.hypot(s, s_ref), (e, e_ref, s, s_ref)


def _standing_mirror(roughness):
    b = SceneBuilder("standing")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    mirror = b.material("mirror", "conductor", color=(0.9,) * 3, roughness=roughness)
    b.plane("Floor", (0, 0, 0), 10, floor, receiver=True)
    b.plane("Mirror", (1.2, 0, 0.55), (1.0, 1.6), mirror, normal=(-1, 0, 0), caster=True)
    b.light("Bulb", "POINT", location=(0.5, 0, 1.4), power=400.0, radius=0.2)
    b.set_camera((-2.6, -1.3, 1.7), (1.2, 0.1, 0.45), lens=35, resolution_x=32, resolution_y=24)
    return b.build()


@pytest.mark.parametrize("roughness", [0.0, 0.5])
def test_a_rough_standing_mirror_throws_the_lit_floor_back_down(roughness):
    """A mirror standing on a floor lit by a bulb: a perfect one sends the floor's light up (a vertical
    mirror keeps a ray's rise), a rough one sends part of it down onto the floor again, light Cycles
    counts in its caustics (camera -> floor -> mirror -> floor -> bulb). The plan's pilots reflected
    rough mirrors as perfect ones and never planned that pass: rough_mirror read 0.973 of Cycles (light
    tracer, 1024 spp), 1.001 with it. Now the plan keeps the pass for the rough mirror alone, and its
    photons land."""
    res = bake(_standing_mirror(roughness), BakeSettings(method="reference", spp=64, seed=1))
    after_bounce = "Bulb -> diffuse -> Mirror -> Floor (after a diffuse bounce)"
    assert (after_bounce in res.stats["plan"]["words"]) == (roughness > 0), res.stats["plan"]["words"]
    assert ("indirect" in res.stats) == (roughness > 0)
    if roughness > 0:
        assert res.stats["indirect"]["Bulb"]["splats"] > 20, res.stats["indirect"]


def test_the_eye_sees_more_of_the_floor_in_a_rough_mirror():
    """The plan's look from the camera (plan.camera_sees) follows a rough mirror's blur: each camera
    ray goes on in the perfect reflection and in one sampled direction, so the box of floor it finds
    seen in the mirror holds the perfect mirror's and reaches further (the pilots test landings
    against that box where a receiver is not seen directly)."""
    from smbs_addon.trace.camera import CameraModel
    from smbs_addon.baking.pilots import camera_sees
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.trace.tracer import Tracer

    boxes = []
    for roughness in (0.0, 0.5):
        sc = _standing_mirror(roughness)
        sc.validate()
        direct, through, _, _, _ = camera_sees(sc, Tracer(sc), CameraModel(sc.camera), make_plan(sc))
        assert direct.tolist() == [True, False]
        boxes.append(through[0])
    smooth, blurred = boxes
    assert (blurred[0] <= smooth[0]).all() and (blurred[1] >= smooth[1]).all()
    size = lambda b: float(np.prod((b[1] - b[0])[:2]))  # noqa: E731  (the floor's box in x and y)
    assert size(blurred) > 1.25 * size(smooth), (smooth, blurred)  # 65.0 against 46.2 m^2


def _rough_slab():
    """A floor seen through a rough glass slab (an open plane, smaller than the floor, as a pool's water) under
    an area light; the camera sees the slab alone."""
    b = SceneBuilder("slab")
    floor = b.material("floor", "diffuse", color=(0.8,) * 3)
    glass = b.material("glass", "dielectric", color=(1, 1, 1), ior=1.33, roughness=0.3)
    b.plane("Floor", (0, 0, 0), 8, floor, receiver=True)
    b.plane("Slab", (0, 0, 1.0), 4, glass, caster=True)
    b.light("Area", "AREA", location=(0.3, 0.2, 3.0), target=(0.3, 0.2, 0), power=400.0, size=1.5)
    b.set_camera((0, 0, 5.0), (0, 0, 0), lens=80, resolution_x=32, resolution_y=24)
    return b.build()


def test_light_after_a_bounce_through_rough_glass_is_gathered():
    """The floor seen only through a rough slab: its light after a diffuse bounce (x0 -> slab's underside ->
    floor x1 -> slab -> light) goes through the rough slab at x1, a path no walk takes. The walks' bakes
    gather it at x1 now (indirect.gather's others), as handoff_gather does at x0, and SMBS makes the light
    tracer's image within 4 sigma; before, gather left it out: 92 below it (4 sigma: 56), and rough_pool_sun
    read 0.876 of Cycles (1.004 now, SMBS 256 spp)."""
    sc = _rough_slab()
    ref = bake(sc, BakeSettings(method="reference", spp=256, batches=8, seed=2))
    res = bake(sc, BakeSettings(method="smbs", spp=32, batches=8, seed=3))
    assert res.stats["eye_pass"]["other_paths_later"] > 30
    (e_ref, s_ref), (e, s) = _energy(ref), _energy(res)
    assert abs(e - e_ref) < 4 * math.hypot(s, s_ref), (e, e_ref, s, s_ref)


def test_ggx_lambda_is_one_function_in_its_three_forms():
    """Smith's Lambda of GGX exists as the numpy form for the tables (microfacet.lambda_ggx), the
    compiled per-lane form (microfacet.lambda1) and the coat's clamped form (coat.lambda_clamped1):
    equal to 1e-12 where the cosine is above the clamp (1e-6), and each guard as documented below it:
    lambda1 is 'infinite' (1e30: no light at grazing incidence) at cosine 0, the clamped ones finite."""
    from smbs_addon.shading.coat import lambda_clamped1
    from smbs_addon.shading.microfacet import lambda1, lambda_ggx

    cos = np.concatenate([np.geomspace(1.5e-6, 1.0, 200), -np.geomspace(1.5e-6, 1.0, 7)])
    for a2 in (1e-7, 1e-4, 0.0625, 0.5, 1.0):
        numpy_form = lambda_ggx(cos, a2)
        lane = np.array([lambda1(c, a2) for c in cos])
        clamped = np.array([lambda_clamped1(c, a2) for c in cos])
        np.testing.assert_allclose(lane, numpy_form, rtol=1e-12, atol=0)
        np.testing.assert_allclose(clamped, numpy_form, rtol=1e-12, atol=0)
        assert lambda1(0.0, a2) == 1e30
        assert np.isfinite(lambda_clamped1(0.0, a2)) and np.isfinite(lambda_ggx(np.array([0.0]), a2)[0])
    assert lambda1(1.0, 0.5) == 0.0  # straight on: no shadowing
