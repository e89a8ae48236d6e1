"""Reflection, refraction and Fresnel (smbs_addon/optics.py) against the textbook.

Conventions (optics.py): w points away from the surface, n is unit, eta =
n_inside / n_outside with n pointing outside; cos_i = w.n > 0 means outside.
Property tests use hypothesis with a derandomized profile (same examples every run).
"""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from smbs_addon.shading.fresnel import fresnel_dielectric, fresnel_schlick
from smbs_addon.shading.optics import reflect, refract

PROFILE = settings(max_examples=300, derandomize=True, deadline=None, database=None)

eta_st = st.floats(1.0001, 2.6)
coord = st.floats(-1.0, 1.0)
vec_st = st.tuples(coord, coord, coord).filter(lambda v: 1e-3 < math.sqrt(sum(x * x for x in v)) <= 1.0)


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def textbook_fresnel(cos_i, n1, n2):
    """Unpolarised reflectance going from index n1 into n2 (1 on TIR)."""
    sin_t = n1 / n2 * math.sqrt(max(0.0, 1 - cos_i * cos_i))
    if sin_t >= 1:
        return 1.0
    cos_t = math.sqrt(1 - sin_t * sin_t)
    rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t)
    rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t)
    return 0.5 * (rs * rs + rp * rp)


# ------------------------------------------------------------------ Fresnel
@pytest.mark.parametrize("eta", [1.0001, 1.33, 1.5, 2.0, 2.42, 2.6])
def test_fresnel_normal_incidence(eta):
    r0 = ((eta - 1) / (eta + 1)) ** 2
    assert fresnel_dielectric(np.array([1.0]), eta)[0] == pytest.approx(r0, rel=1e-12)
    assert fresnel_dielectric(np.array([-1.0]), eta)[0] == pytest.approx(r0, rel=1e-12)  # from inside


@given(eta=eta_st, x=st.floats(1e-6, 1.0))
@PROFILE
def test_fresnel_total_internal_reflection_from_inside(eta, x):
    cos_c = math.sqrt(1 - 1 / eta**2)  # critical angle, seen from inside
    cos_i = cos_c * x * (1 - 1e-9)  # strictly beyond it (grazing side)
    assert fresnel_dielectric(np.array([-cos_i]), eta)[0] == 1.0


@given(eta=eta_st, cos_i=st.floats(1e-6, 1.0))
@PROFILE
def test_fresnel_matches_textbook_both_sides(eta, cos_i):
    out = fresnel_dielectric(np.array([cos_i]), eta)[0]
    assert out == pytest.approx(textbook_fresnel(cos_i, 1.0, eta), rel=1e-9, abs=1e-15)
    inside = fresnel_dielectric(np.array([-cos_i]), eta)[0]
    assert inside == pytest.approx(textbook_fresnel(cos_i, eta, 1.0), rel=1e-9, abs=1e-15)
    assert 0.0 <= out <= 1.0 and 0.0 <= inside <= 1.0


@given(eta=eta_st, cos_i=st.floats(1e-4, 1.0))
@PROFILE
def test_fresnel_reciprocity(eta, cos_i):
    """F from outside at theta_i equals F from inside at the refracted angle."""
    sin_t = math.sqrt(1 - cos_i**2) / eta
    cos_t = math.sqrt(1 - sin_t**2)
    a = fresnel_dielectric(np.array([cos_i]), eta)[0]
    b = fresnel_dielectric(np.array([-cos_t]), eta)[0]
    assert a == pytest.approx(b, rel=1e-9, abs=1e-14)


def test_fresnel_array_and_scalar_eta_broadcast():
    cos_i = np.array([1.0, 0.5, -0.5, -0.1])
    eta = np.array([1.5, 1.5, 1.5, 1.5])
    np.testing.assert_array_equal(fresnel_dielectric(cos_i, eta), fresnel_dielectric(cos_i, 1.5))
    assert fresnel_dielectric(cos_i, 1.5)[3] == 1.0  # sin_t = 1.5 * 0.995 > 1


def test_fresnel_schlick_endpoints():
    f0 = np.array([0.04, 0.5, 0.9])
    np.testing.assert_allclose(fresnel_schlick(np.array([1.0]), f0)[0], f0, rtol=1e-15)
    np.testing.assert_allclose(fresnel_schlick(np.array([0.0]), f0)[0], 1.0, rtol=1e-15)
    np.testing.assert_allclose(fresnel_schlick(np.array([0.5]), f0)[0], f0 + (1 - f0) * 0.5**5, rtol=1e-15)


def _metal_scene(fresnel, color, metal):
    from smbs_addon.scene import arrays as S
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder("metal")
    b.material("Metal", S.CONDUCTOR, color=color, fresnel=fresnel, metal=metal)
    b.mesh("Mirror", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], 0, caster=True)
    return b.build()


@given(n=st.floats(1.01, 4.0), mu=st.floats(0.0, 1.0))
@PROFILE
def test_a_conductor_without_extinction_is_a_dielectric(n, mu):
    """The physical conductor's Fresnel (optics.fresnel_conductor1, the Metallic BSDF's Physical
    Conductor) with k = 0 is the dielectric Fresnel of index n, an independent formula."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.shading.fresnel import specular_weights

    sc = _metal_scene(S.FRESNEL_CONDUCTOR, (0.5,) * 3, (n, n, n, 0.0, 0.0, 0.0))
    R, T = specular_weights(sc, np.zeros(1, np.int64), np.array([mu]))
    assert R[0, 0] == pytest.approx(fresnel_dielectric(np.array([mu]), n)[0], rel=1e-9, abs=1e-12)
    assert not T.any()


def test_conductor_fresnel_at_normal_and_grazing_incidence():
    """A physical conductor reflects ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) head on and everything at
    grazing incidence, from either side, with no NaN where n or k is 0 in a channel; values in [0, 1]."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.shading.fresnel import specular_weights

    n, k = np.array([0.2, 1.1, 0.0]), np.array([3.6, 0.0, 2.0])
    sc = _metal_scene(S.FRESNEL_CONDUCTOR, (0.5,) * 3, np.concatenate([n, k]))
    mu = np.array([1.0, -1.0, 0.0, 1e-9, 0.3, -0.3])
    R, _ = specular_weights(sc, np.zeros(len(mu), np.int64), mu)
    head_on = ((n - 1) ** 2 + k ** 2) / ((n + 1) ** 2 + k ** 2)
    np.testing.assert_allclose(R[0], head_on, rtol=1e-12)
    np.testing.assert_array_equal(R[1], R[0])
    np.testing.assert_allclose(R[2], 1.0, rtol=1e-12)
    np.testing.assert_array_equal(R[4], R[5])
    assert np.all(np.isfinite(R)) and np.all((R >= 0) & (R <= 1))


def test_f82_tint_matches_its_definition():
    """Cycles' F82-Tint metal (a Principled metal's Specular Tint, the Metallic BSDF's Edge Tint): F0
    head on, 1 at grazing incidence, and at cos = 1/7 (about 82 degrees) the tint times Schlick's value
    there, the model's definition; a white tint is Schlick's F0 towards white everywhere."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.shading.fresnel import f82_tint_metal
    from smbs_addon.shading.fresnel import specular_weights

    f0, tint = np.array([0.9, 0.6, 0.3]), np.array([1.0, 0.5, 0.2])
    sc = _metal_scene(S.FRESNEL_SCHLICK, f0, f82_tint_metal(f0, tint))
    mu = np.array([1.0, 0.0, 1.0 / 7.0, 0.5])
    R, _ = specular_weights(sc, np.zeros(4, np.int64), mu)
    np.testing.assert_allclose(R[0], f0, rtol=1e-12)
    np.testing.assert_allclose(R[1], 1.0, rtol=1e-12)
    np.testing.assert_allclose(R[2], tint * fresnel_schlick(np.array([1.0 / 7.0]), f0)[0], rtol=1e-12)
    assert np.all(R[3] <= fresnel_schlick(np.array([0.5]), f0)[0])
    assert not f82_tint_metal(f0, np.ones(3)).any()


def test_a_rough_conductors_mean_fresnel_is_cycles_f82_fit():
    """Multiscatter GGX on a rough physical conductor takes Cycles' mean Fresnel (fresnel_conductor_Fss:
    the F82 model fitted at cos 1 and 1/7): within 1% of the conductor's own hemispherical mean (an
    independent quadrature), and exact for a Schlick metal, whose fit is itself (F0 + (1 - F0) / 21)."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.shading.fresnel import specular_weights
    from smbs_addon.shading.energy import _f82_fit_mean

    sc = _metal_scene(S.FRESNEL_CONDUCTOR, (0.5,) * 3, (0.27, 0.68, 1.32, 3.61, 2.63, 2.29))
    mu = (np.arange(20000) + 0.5) / 20000
    R, _ = specular_weights(sc, np.zeros(len(mu), np.int64), mu)
    mean = 2.0 * (R * mu[:, None]).mean(axis=0)
    f0, f82 = specular_weights(sc, np.zeros(2, np.int64), np.array([1.0, 1.0 / 7.0]))[0]
    fit = _f82_fit_mean(f0, f82)
    np.testing.assert_allclose(fit, mean, rtol=0.01)
    f0 = np.array([0.04, 0.5, 0.9])
    np.testing.assert_allclose(_f82_fit_mean(f0, fresnel_schlick(np.array([1.0 / 7.0]), f0)[0]),
                               f0 + (1 - f0) / 21.0, rtol=1e-12)


# ---------------------------------------------------------------- refraction
@given(w=vec_st, n=vec_st, eta=eta_st)
@PROFILE
def test_refract_obeys_snell_and_reverses(w, n, eta):
    w, n = unit(w), unit(n)
    c = float(w @ n)
    t, ok = refract(w[None], n[None], eta)
    t, ok = t[0], bool(ok[0])
    assert not np.isnan(t).any()
    n1, n2 = (1.0, eta) if c >= 0 else (eta, 1.0)
    sin_i = float(np.linalg.norm(np.cross(w, n)))  # better conditioned than sqrt(1 - c^2)
    if n1 / n2 * sin_i >= 1.0 + 1e-12:
        assert not ok and np.all(t == 0)
        return
    if n1 / n2 * sin_i > 1.0 - 1e-9:
        return  # too close to the critical angle to ask for more
    assert ok
    assert np.linalg.norm(t) == pytest.approx(1.0, abs=1e-12)
    ct = float(t @ n)
    assert ct * c <= 0  # crosses to the other side
    sin_t = float(np.linalg.norm(np.cross(t, n)))
    assert n1 * sin_i == pytest.approx(n2 * sin_t, rel=1e-9, abs=1e-14)  # Snell
    # coplanar with w and n, on the other side of n's line (the tangential parts oppose)
    assert abs(np.linalg.det(np.stack([w, n, t]))) < 1e-9
    assert float((w - c * n) @ (t - ct * n)) <= 1e-12
    if abs(c) < 1e-4:
        return  # at grazing incidence the way back starts at the critical angle (ill-conditioned)
    back, ok_back = refract(t[None], n[None], eta)
    assert ok_back[0]
    np.testing.assert_allclose(back[0], w, atol=1e-10)


@given(n=vec_st, eta=eta_st, x=st.floats(1e-6, 0.999))
@PROFILE
def test_total_internal_reflection_gives_zero_not_nan(n, eta, x):
    n = unit(n)
    s = unit(np.cross(n, [0.3, 0.5, 0.7]) if abs(n @ unit([0.3, 0.5, 0.7])) < 0.99 else np.cross(n, [1, 0, 0]))
    cos_c = math.sqrt(1 - 1 / eta**2)
    cos_i = x * cos_c  # beyond the critical angle
    w = -cos_i * n + math.sqrt(1 - cos_i**2) * s  # inside (w.n < 0)
    t, ok = refract(w[None], n[None], eta)
    assert not ok[0]
    assert np.all(t == 0) and not np.isnan(t).any()


def test_refract_normal_incidence_and_known_angle():
    n = np.array([[0.0, 0.0, 1.0]])
    t, ok = refract(np.array([[0.0, 0.0, 1.0]]), n, 1.5)
    assert ok[0] and np.allclose(t[0], [0, 0, -1], atol=0)
    # 60 degrees in air into water (1.33): sin_t = sin 60 / 1.33
    w = np.array([[-math.sin(math.pi / 3), 0.0, math.cos(math.pi / 3)]])
    t, ok = refract(w, n, 1.33)
    st_ = math.sin(math.pi / 3) / 1.33
    np.testing.assert_allclose(t[0], [st_, 0.0, -math.sqrt(1 - st_**2)], atol=1e-15)


def test_refract_batch_with_per_lane_eta():
    rng = np.random.default_rng(0)
    w = rng.normal(size=(1000, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    n = np.tile([0.0, 0.0, 1.0], (1000, 1))
    eta = rng.uniform(1.0001, 2.6, 1000)
    t, ok = refract(w, n, eta)
    for i in range(0, 1000, 97):
        ti, oki = refract(w[i:i + 1], n[i:i + 1], eta[i])
        assert oki[0] == ok[i]
        np.testing.assert_array_equal(ti[0], t[i])
    assert not np.isnan(t).any()
    # TIR exactly where sin_t would exceed 1, from inside only
    sin_i = np.sqrt(1 - w[:, 2] ** 2)
    tir = (w[:, 2] < 0) & (eta * sin_i > 1)
    assert np.array_equal(~ok, tir)


# ---------------------------------------------------------------- reflection
@given(w=vec_st, n=vec_st)
@PROFILE
def test_reflect_is_an_involution_and_mirrors(w, n):
    w, n = unit(w), unit(n)
    r = reflect(w[None], n[None])[0]
    np.testing.assert_allclose(reflect(r[None], n[None])[0], w, atol=1e-14)
    assert np.linalg.norm(r) == pytest.approx(1.0, abs=1e-14)
    assert float(r @ n) == pytest.approx(float(w @ n), abs=1e-14)  # same side, same angle
    # tangential component flips
    np.testing.assert_allclose(r - (r @ n) * n, -(w - (w @ n) * n), atol=1e-14)
    # the normal's sign does not matter
    np.testing.assert_allclose(reflect(w[None], -n[None])[0], r, atol=1e-15)


def test_a_far_tinted_glass_under_a_film_keeps_its_weights_in_range():
    """A Specular Tint far above white under a thin film: Cycles scales the film's reflectance by up to
    f0 / F0 (here 31), past 1, and its transmission 1 - F turns negative; ours keeps R in [0, 1] and
    T >= 0 (the bake fuzz found it: glass of index near 1, a film of 1 nm and index 1, tint 31)."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.scene.builder import SceneBuilder
    from smbs_addon.shading.fresnel import specular_weights

    b = SceneBuilder("tint")
    m = b.material("glass", S.DIELECTRIC, color=(1.0, 1.0, 1.0), ior=1.02, metal=(30.0, 0.0, 30.0, 0, 0, 0),
                   film=(1.0, 1.0))
    b.plane("Pane", (0, 0, 1), 1, m, caster=True)
    b.light("Bulb", "POINT", location=(0, 0, 3), power=10.0)
    b.set_camera((0, -3, 2), (0, 0, 0), resolution_x=4, resolution_y=4)
    sc = b.build()
    cos = np.concatenate([np.linspace(-1.0, 1.0, 401), [1e-9, -1e-9]])
    R, T = specular_weights(sc, np.full(len(cos), m), cos)
    assert np.all((R >= 0) & (R <= 1)) and np.all(T >= 0) and np.all(np.isfinite(R + T))
    inner = cos > 0.05  # from outside (inside, past the critical angle, and at grazing every channel reflects all)
    assert R[inner, 0].max() == 1.0 and R[inner, 1].max() < 1.0  # the tinted channels reach the bound, the white not
