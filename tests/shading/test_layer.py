"""The glossy layer over a Principled BSDF's diffuse (smbs_addon/layer.py): the share of the light
it leaves the diffuse towards the eye, 1 - A(mu), against the smooth limit's exact Fresnel and
against what Cycles renders."""
import numpy as np
import pytest

from smbs_addon.shading import coat as layer
from smbs_addon.shading.fresnel import fresnel_dielectric
from smbs_addon.shading.optics import coat_factor

# Cycles 5.0.1 (the bpy module), measured: a plane of Blender's default Principled BSDF (Base
# Color 0.8, Roughness 0.5, IOR 1.5) and one of Diffuse BSDF 0.8 under a sun, seen by an
# orthographic camera at cosine mu, 64 spp; (Principled - Principled with Base Color black) /
# Diffuse is the diffuse's weight under the glossy layer (the black one holds the glossy alone)
CYCLES_DEFAULT = {1.0: 0.9626, 0.8: 0.9580, 0.6: 0.9439, 0.4: 0.9132, 0.356: 0.9030, 0.2: 0.8566}


# Cycles 5.0.1, measured: a plane of Diffuse BSDF 0.8 of Roughness sigma over the same of Roughness 0
# under a sun of elevation angle `sun` from the zenith and azimuth `az`, the orthographic camera at
# cosine mu (looking along +y); (mu, sun, az, sigma) -> ratio
CYCLES_OREN_NAYAR = {(0.356, 40, 90, 0.5): 0.9139, (0.356, 40, 90, 1.0): 0.8457, (0.356, 40, 0, 0.5): 1.2565,
                     (0.356, 40, 0, 1.0): 1.4544, (0.356, 40, 180, 0.5): 0.6512, (0.356, 40, 180, 1.0): 0.3790,
                     (0.8, 60, 0, 1.0): 1.3806, (0.5, 20, 45, 0.5): 1.0342}


@pytest.mark.parametrize("case", sorted(CYCLES_OREN_NAYAR))
def test_a_rough_diffuse_is_cycles_oren_nayar(case):
    """Cycles' Diffuse BSDF of Roughness > 0 (Fujii's Oren-Nayar with OpenPBR's multiple
    scattering): 0.38-1.45 of Lambert in these cases, matched within 0.05%; coat_factor of a rough
    diffuse without a coat is that ratio."""
    import math

    mu, sun, az, sigma = case
    th = math.acos(mu)
    wv = np.array([0.0, -math.sin(th), math.cos(th)])
    s, a = math.radians(sun), math.radians(az)
    # Blender's sun of rotation (sun, 0, az) shines along -(R z): its direction towards the light is R z
    wl = np.array([math.sin(s) * math.sin(a), -math.sin(s) * math.cos(a), math.cos(s)])
    ratio = layer.oren_nayar_ratio1(sigma, 0.8, wv[2], wl[2], wv @ wl)
    assert ratio == pytest.approx(CYCLES_OREN_NAYAR[case], rel=5e-4)
    scene = _one_material_scene((0.0, 0.0, 0.0, 1.0, sigma, 0.0, 0.0, 0.0))
    scene.mat_color[0] = 0.8
    k = coat_factor(scene, np.array([0]), np.array([[0.0, 0.0, 1.0]]), wv[None], wl[None])
    np.testing.assert_allclose(k[0], ratio, rtol=1e-12)


def test_a_smooth_layer_takes_exactly_the_fresnel_reflectance():
    """Roughness 0: the layer is a perfect dielectric mirror, A = F(mu) exactly."""
    w = layer.layer_weights(1.5, 0.0)
    mu = np.linspace(0.0, 1.0, layer.MU_STEPS + 1)[1:]
    np.testing.assert_allclose(w[1:], 1.0 - fresnel_dielectric(mu, 1.5), atol=5e-5)  # alpha 1e-4, not 0
    assert w[-1] == pytest.approx(0.96, abs=1e-9)  # F0 of IOR 1.5


@pytest.mark.parametrize("mu", sorted(CYCLES_DEFAULT))
def test_blenders_default_material_weighs_its_diffuse_as_cycles_does(mu):
    """Within 0.35% of Cycles from mu = 1 down to 0.356 (its lookup tables are coarse: 16-32 steps);
    at mu = 0.2 within 1%. Without the layer the caustic on such a floor read 1.15 of Cycles."""
    tab = layer.table(_one_material_scene((1.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0)))
    ours = float(layer.weight(tab, np.array([0]), np.array([mu]))[0])
    assert ours == pytest.approx(CYCLES_DEFAULT[mu], rel=0.0035 if mu > 0.3 else 0.01)


def test_the_weight_is_one_exactly_without_a_layer_and_falls_with_the_layer():
    scene = _one_material_scene((0.0,) * 8)
    assert not layer.has_layers(scene)
    tab = layer.table(scene)
    cos = np.linspace(-1.0, 1.0, 101)
    assert np.all(layer.weight(tab, np.zeros(101, np.int64), cos) == 1.0)  # bit for bit: x 1.0
    rough = [float(layer.weight(layer.table(_one_material_scene((1.5, r, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0))),
                                np.array([0]), np.array([0.5]))[0]) for r in (0.0, 0.5, 1.0)]
    assert 0.9 < rough[0] < rough[1] < rough[2] < 1.0  # rougher: less reflected at this slant
    tinted = layer.layer_weights(1.5, 0.5, 0.5)
    np.testing.assert_allclose(1.0 - tinted, 0.5 * (1.0 - layer.layer_weights(1.5, 0.5)), atol=1e-12)


def test_specular_ior_level_scales_the_reflectance_at_normal_incidence():
    eta, tint = layer.principled_layer(1.5, 0.5, (1.0, 1.0, 1.0))
    assert eta == pytest.approx(1.5) and tint == 1.0
    eta, tint = layer.principled_layer(1.5, 1.0, (0.2, 0.7, 0.4))
    assert ((eta - 1) / (eta + 1)) ** 2 == pytest.approx(0.08) and tint == pytest.approx(0.7)
    assert layer.principled_layer(1.5, 0.0, (1.0, 1.0, 1.0)) == (0.0, 0.0)


def _one_material_scene(lay):
    from smbs_addon.scene import arrays as S
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder()
    m = b.material("Floor", S.DIFFUSE, layer=lay)
    b.mesh("Floor", np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]]), m)
    b.set_camera(matrix=np.eye(4))
    return b.build()


def test_the_coat_factor_is_what_cycles_closure_sampling_leaves_the_diffuse_label():
    """Cycles picks a Principled BSDF's closure by sample weight (diffuse: colour x (1 - A); coat:
    A), samples its direction (cosine; the coat's visible normals), weighs it by every closure's
    eval over their combined pdf, and labels the path by the closure it picked; the caustics-off
    render stops the diffuse-labelled paths at the glass. Simulated here sample by sample (2M
    samples), the diffuse-labelled weight that lands in a cone of 8 degrees around a direction
    is the integral of coat_factor x the coated diffuse over that cone, within 3 standard
    errors, for light from above and along the coat's lobe (where the factor is 0.93)."""
    rng = np.random.default_rng(7)
    lay = (1.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0)
    base = 0.8
    scene = _one_material_scene(lay)
    scene.mat_color[0] = base
    mu_o = 0.356
    wv = np.array([-np.sqrt(1 - mu_o ** 2), 0.0, mu_o])  # towards the eye; the lobe leans to +x
    one_minus_a = float(layer.weight(layer.table(scene), np.array([0]), np.array([mu_o]))[0])
    gain = float(layer.weight(layer.gain_table(scene), np.array([0]), np.array([mu_o]))[0])
    a2 = 0.5 ** 4
    sw_d, sw_g = base * one_minus_a, 1.0 - one_minus_a
    p_d = sw_d / (sw_d + sw_g)

    def lam(c):
        return 0.5 * (np.sqrt(1 + a2 * np.maximum(1 / np.maximum(c * c, 1e-12) - 1, 0)) - 1)

    def evals(w):  # (eval_d, eval_g, pdf_d, pdf_g) of directions w (N,3), cosines included in evals
        h = w + wv
        h /= np.linalg.norm(h, axis=1)[:, None]
        d = a2 / (np.pi * (1 + (a2 - 1) * h[:, 2] ** 2) ** 2)
        ci = np.maximum(w[:, 2], 0.0)
        g2 = 1 / (1 + lam(mu_o) + lam(np.maximum(ci, 1e-9)))
        f = fresnel_dielectric(h @ wv, 1.5)
        up = ci > 0
        return (np.where(up, base * one_minus_a * ci / np.pi, 0.0), np.where(up, gain * f * d * g2 / (4 * mu_o), 0.0),
                ci / np.pi, np.where(up, d / (4 * mu_o * (1 + lam(mu_o))), 0.0))

    n = 2_000_000
    diffuse = rng.random(n) < p_d
    u1, u2 = rng.random(n), rng.random(n)
    w = np.empty((n, 3))
    r, phi = np.sqrt(u1[diffuse]), 2 * np.pi * u2[diffuse]
    w[diffuse] = np.column_stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u1[diffuse])])
    k = ~diffuse  # the coat: Heitz's visible normals of the view, then the mirror direction
    alpha = 0.25
    vh = np.array([alpha * wv[0], 0.0, wv[2]])
    vh /= np.linalg.norm(vh)
    t1 = np.array([0.0, 1.0, 0.0]) if abs(vh[0]) > 1e-7 else np.array([1.0, 0.0, 0.0])
    t2 = np.cross(vh, t1)
    r, phi = np.sqrt(u1[k]), 2 * np.pi * u2[k]
    p1, p2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1 + vh[2])
    p2 = (1 - s) * np.sqrt(1 - p1 * p1) + s * p2
    nh = p1[:, None] * t1 + p2[:, None] * t2 + np.sqrt(np.maximum(0, 1 - p1 * p1 - p2 * p2))[:, None] * vh
    h = np.column_stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 0)])
    h /= np.linalg.norm(h, axis=1)[:, None]
    w[k] = 2 * (h @ wv)[:, None] * h - wv
    e_d, e_g, q_d, q_g = evals(w)
    weight = np.where(diffuse, (e_d + e_g) / np.maximum(p_d * q_d + (1 - p_d) * q_g, 1e-300), 0.0)
    cone = np.cos(np.radians(8.0))
    for theta in (0.0, 30.0):  # from straight above; 30 degrees towards the coat's lobe
        axis = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
        inside = (w @ axis) > cone
        got = weight * inside
        mean, se = got.mean(), got.std() / np.sqrt(n)
        # the same integral from the closed form, over uniform directions in the cone
        m = 400_000
        c = 1 - rng.random(m) * (1 - cone)
        ph = 2 * np.pi * rng.random(m)
        sn = np.sqrt(1 - c * c)
        e1 = np.cross(axis, [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        wl = c[:, None] * axis + (sn * np.cos(ph))[:, None] * e1 + (sn * np.sin(ph))[:, None] * e2
        kf = coat_factor(scene, np.zeros(m, np.int64), np.tile([0.0, 0.0, 1.0], (m, 1)), np.tile(wv, (m, 1)), wl)[:, 0]
        want = (kf * base * one_minus_a * wl[:, 2] / np.pi).mean() * 2 * np.pi * (1 - cone)
        assert abs(mean - want) < 3 * se + 0.002 * want, (theta, mean, want, se)
        if theta == 30.0:
            assert kf.mean() < 0.96  # the check can see the factor: it is far from 1 there
