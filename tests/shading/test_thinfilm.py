"""A thin film's iridescence (smbs_addon/thinfilm.py) against an independent estimator: the film's
reflectance per wavelength from the amplitudes of the two interfaces, r = (r12 + r23 e^(i delta)) /
(1 + r12 r23 e^(i delta)), integrated against each channel's colour matching function over 360-830 nm.
Cycles' way (and ours) instead sums three orders of the Airy series against a table of the functions'
Fourier transforms; for films whose interfaces reflect little the two agree to the table's own error.
The table itself agrees with Cycles' (shader.tables' table_thin_film_cmf, taken to Rec.709 by the same
matrix) to 0.005 on average, 0.03 at most (measured when it was written, 2026-11-28)."""
import math

import numpy as np
import pytest

from smbs_addon.shading import fresnel
from smbs_addon.scene import arrays as S
from smbs_addon.shading import thinfilm as T
from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.core.errors import SceneError


def _amplitudes(n1, c1, n2, c2):
    """Fresnel amplitudes (s, p) from index n1 (cosine c1) into n2 (cosine c2), complex."""
    rs = (n1 * c1 - n2 * c2) / (n1 * c1 + n2 * c2)
    rp = (n2 * c1 - n1 * c2) / (n2 * c1 + n1 * c2)
    return rs, rp


def _spectral(thickness, n_film, n_sub, cos1):
    """The film's RGB reflectance (ambient index 1) by integration over wavelength."""
    lam = np.linspace(360.0, 830.0, 9401)
    s1 = math.sqrt(1.0 - cos1 * cos1)
    c2 = np.sqrt(1.0 - (s1 / n_film) ** 2 + 0j)
    c3 = np.sqrt(1.0 - (s1 / n_sub) ** 2 + 0j)
    delta = 4.0 * np.pi * n_film * thickness * c2 / lam
    R = 0.0
    for r12, r23 in zip(_amplitudes(1.0, cos1, n_film, c2), _amplitudes(n_film, c2, n_sub, c3)):
        e = np.exp(1j * delta)
        R = R + 0.5 * np.abs((r12 + r23 * e) / (1.0 + r12 * r23 * e)) ** 2
    rgb = T.cmf_xyz(lam) @ T._XYZ_TO_REC709.T
    return (R[:, None] * rgb).sum(axis=0) / rgb.sum(axis=0)


@pytest.mark.parametrize("thickness,n_film,n_sub,cos1", [
    (250.0, 1.33, 1.5, 1.0), (500.0, 1.33, 1.5, 0.7), (400.0, 1.38, 1.52, 0.4), (900.0, 1.3, 1.45, 0.9),
    (150.0, 1.45, 1.33, 0.8)])
def test_a_weak_film_reflects_what_its_spectrum_integrates_to(thickness, n_film, n_sub, cos1):
    """Interfaces of small reflectance (r123 < 1e-3: the Airy series' terms past the third are below 1e-9)
    at normal and oblique incidence: within 0.002 of the spectral integral, per channel (bare glass
    reflects 0.02-0.04: the film moves it by more than ten times that)."""
    ours = np.array(T.dielectric_film1(thickness, n_film, cos1, n_sub))
    truth = _spectral(thickness, n_film, n_sub, cos1)
    assert np.abs(ours - truth).max() < 0.002, (ours, truth)
    assert np.ptp(truth) > 0.005  # the film colours the reflection: the test can tell a wrong phase


def test_a_strong_film_still_follows_the_spectrum():
    """A high-index film (2.2 over glass 1.5, 280 nm: film_ball's): interfaces reflecting 0.14 and 0.04,
    the series cut after three orders as Cycles cuts it: within 0.01 per channel."""
    for cos1 in (1.0, 0.6):
        ours = np.array(T.dielectric_film1(280.0, 2.2, cos1, 1.5))
        truth = _spectral(280.0, 2.2, 1.5, cos1)
        assert np.abs(ours - truth).max() < 0.01, (cos1, ours, truth)


def test_no_film_is_the_bare_fresnel_and_total_internal_reflection_stays_whole():
    """At thickness 0 the film's index fades to the medium's: the dielectric's own Fresnel (0.04 for glass
    1.5), the physical conductor's, F82-Tint's; from inside the glass past the critical angle, 1."""
    bare = fresnel.fresnel_dielectric1(0.8, 1.5)
    assert np.allclose(T.dielectric_film1(0.0, 1.8, 0.8, 1.5), bare, atol=1e-12)
    assert np.allclose(T.dielectric_film1(0.0, 1.8, -0.8, 1.5), fresnel.fresnel_dielectric1(-0.8, 1.5), atol=1e-12)
    nk = (0.2, 0.9, 1.1, 3.9, 2.4, 2.2)
    want = [fresnel.fresnel_conductor1(0.6, nk[c], nk[c + 3]) for c in range(3)]
    assert np.allclose(T.conductor_film1(0.0, 1.5, 0.6, nk), want, atol=1e-12)
    f0, b = (0.9, 0.7, 0.3), (0.1, 0.2, 0.0)
    want = [T._f82(0.6, f0[c], b[c]) for c in range(3)]
    assert np.allclose(T.f82_film1(0.0, 1.5, 0.6, f0, b), want, atol=1e-6)
    assert T.dielectric_film1(300.0, 1.33, -0.5, 1.5) == (1.0, 1.0, 1.0)  # sin 0.866 x 1.5 > 1


def test_the_film_reflects_within_zero_and_one_everywhere():
    rng = np.random.default_rng(2)
    for _ in range(300):
        th, nf, ns, c = rng.uniform(0, 2000), rng.uniform(1.0, 3.0), rng.uniform(1.0, 2.5), rng.uniform(-1, 1)
        r = T.dielectric_film1(th, nf, c, ns)
        assert all(0.0 <= x <= 1.0 for x in r), (th, nf, ns, c, r)
        nk = tuple(rng.uniform(0.1, 4.0, 6))
        r = T.conductor_film1(th, nf, abs(c), nk)
        assert all(0.0 <= x <= 1.0 for x in r), (th, nf, abs(c), nk, r)


def test_a_filmed_glass_transmits_what_it_does_not_reflect():
    """specular_weights: a Glass BSDF under a film reflects the film's reflectance per channel and
    transmits the rest, at both faces; without the film, the scalar Fresnel."""
    b = SceneBuilder("film")
    b.material("Filmed", "dielectric", color=(1, 1, 1), ior=1.5, film=(280.0, 2.2))
    b.material("Bare", "dielectric", color=(1, 1, 1), ior=1.5)
    sc = b.build()
    assert sc.mat_film.shape == (2, 2) and sc.mat_film[1, 0] == 0
    cos = np.array([0.9, -0.9, 0.3])
    R, Tr = fresnel.specular_weights(sc, np.zeros(3, int), cos)
    assert np.allclose(R + Tr, 1.0)
    assert np.allclose(R, [T.dielectric_film1(280.0, 2.2, c, 1.5) for c in cos])
    assert np.ptp(R[0]) > 0.05  # coloured
    R, Tr = fresnel.specular_weights(sc, np.ones(3, int), cos)
    assert np.allclose(R[:, 0], [fresnel.fresnel_dielectric1(c, 1.5) for c in cos]) and np.ptp(R, axis=1).max() == 0


def test_a_film_that_cannot_be_is_refused_with_the_material_named():
    b = SceneBuilder("bad")
    b.material("Soap", "dielectric", film=(-5.0, 1.33))
    with pytest.raises(SceneError, match="material 'Soap': a thin film needs"):
        b.build().validate()
    b = SceneBuilder("bad")
    b.material("Oil", "conductor", film=(300.0, 0.0))
    with pytest.raises(SceneError, match="material 'Oil'"):
        b.build().validate()
    assert S.Scene.__dataclass_fields__["mat_film"] is not None
