"""A thin film's iridescence (Thin Film Thickness and IOR of the Principled, Glass and Metallic BSDF),
as Cycles computes it (Blender 4.2 on: kernel/closure/bsdf_util.h's fresnel_iridescence_channel, after
Belcour and Barla 2017, "A Practical Extension to Microfacet Theory for the Modeling of Varying
Iridescence").

Light reflected by a film of index n_f and thickness d over a substrate interferes with itself: per
polarisation, the Airy sum R = R12 + Rs + sum_m 2 C_m cos(m (2 pi OPD / lambda + phi)) over the orders m of
the light's round trips in the film, OPD = 2 n_f d cos(theta_2) the optical path difference, phi the
phase shifts at the two interfaces. Integrated against a channel's sensitivity S_c(lambda), the cosine
becomes the Fourier transform of S_c in wavenumber nu = 1 / lambda: R_c = R12 + Rs + sum_m 2 C_m
Re[exp(i m phi) conj(S^_c(m OPD))]. Cycles keeps S^_c in a table of 512 complex values for 2 pi OPD from
0 to 60 um, interpolated linearly, the first three orders (m = 1..3), the mean of the two polarisations,
clamped to [0, 1]; so do we.

The table is made here (sensitivity_table) from the CIE 1931 2-degree colour matching functions in the
analytic multi-lobe fit of Wyman, Sloan and Shirley (2013, JCGT 2(2)), taken to linear Rec.709 (the
working space of Blender's default configuration) and transformed by direct quadrature over wavenumber;
each channel divided by its value at OPD 0, so that a film of no effect leaves white white. Cycles
resamples the tabulated CIE data and takes an FFT: the tables agree to the fit's error (about 1% of the
functions' peaks).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..core.jit import JIT, LANES

# The functions a caller's kernel reaches (dielectric_film1, f82_film1, conductor_film1, iridescence1) are
# compiled apart and called, not inlined: optics.specular_weights1 is inlined into every path kernel, and
# nine inlined copies of the Airy sum in each made the first compile of the kernels take many minutes.

CUTOFF = 0.1  # nm: Cycles' THINFILM_THICKNESS_CUTOFF, below it the film is not there
TABLE_SIZE = 512  # Cycles' THIN_FILM_TABLE_SIZE
TABLE_SPAN = 60000.0  # nm of 2 pi OPD the table covers (index (size - 1) x 2 pi OPD / span)
ORDERS = 3  # the Airy sum's orders past the first: m = 1..3

# XYZ (CIE 1931) to linear Rec.709 with a D65 white (IEC 61966-2-1)
_XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                           [-0.9692660, 1.8760108, 0.0415560],
                           [0.0556434, -0.2040259, 1.0572252]])

# Wyman, Sloan and Shirley's multi-lobe fit: per function, lobes (weight, mean nm, sigma below, sigma above)
_LOBES = (((1.056, 599.8, 37.9, 31.0), (0.362, 442.0, 16.0, 26.7), (-0.065, 501.1, 20.4, 26.2)),
          ((0.821, 568.8, 46.9, 40.5), (0.286, 530.9, 16.3, 31.1)),
          ((1.217, 437.0, 11.8, 36.0), (0.681, 459.0, 26.0, 13.8)))


def cmf_xyz(lam: np.ndarray) -> np.ndarray:
    """(N,3) the CIE 1931 colour matching functions x, y, z at wavelengths lam (nm), the analytic fit."""
    lam = np.asarray(lam, np.float64)
    out = np.zeros(lam.shape + (3,))
    for c, lobes in enumerate(_LOBES):
        for w, mu, s1, s2 in lobes:
            t = (lam - mu) / np.where(lam < mu, s1, s2)
            out[..., c] += w * np.exp(-0.5 * t * t)
    return out


def sensitivity_table(size: int = TABLE_SIZE, span: float = TABLE_SPAN) -> np.ndarray:
    """(6, size): per Rec.709 channel the real parts, then the imaginary parts, of the Fourier transform
    S^_c(x) = int S_c(nu) exp(-i x nu) dnu / int S_c(nu) dnu at x = 2 pi OPD = span j / (size - 1) (nm),
    S_c the channel's sensitivity over wavenumber nu = 1 / lambda (its density over lambda times
    lambda^2)."""
    lam = np.linspace(360.0, 830.0, 4701)  # 0.1 nm: the integrand's phase moves < 0.2 rad a step at 60 um
    rgb = cmf_xyz(lam) @ _XYZ_TO_REC709.T  # (N,3)
    nu = 1.0 / lam
    dens = rgb * (lam * lam)[:, None]  # S(nu) = S(lambda) |d lambda / d nu|
    w = np.gradient(nu)[:, None] * -1.0  # trapezoid-like weights of d nu (nu falls as lambda grows)
    x = np.linspace(0.0, span, size)
    phase = np.outer(x, nu)  # (size, N)
    re = np.cos(phase) @ (dens * w)
    im = -np.sin(phase) @ (dens * w)
    dc = re[0].copy()
    return np.ascontiguousarray(np.concatenate([(re / dc).T, (im / dc).T]))


TABLE = sensitivity_table()


@njit(inline="always", **JIT)
def _lookup(table, row, x):
    """Cycles' lookup_table_read: table[row] at x in [0, 1] over its entries, linearly interpolated,
    clamped at the ends."""
    n = table.shape[1]
    f = min(max(x, 0.0), 1.0) * (n - 1)
    i = min(int(f), n - 2)
    t = f - i
    return (1.0 - t) * table[row, i] + t * table[row, i + 1]


@njit(**JIT)
def _dielectric_polarized(cos_i, eta):
    """Fresnel reflectances (Rs, Rp) of light at incidence cosine cos_i onto a medium of relative index
    eta, the cosine of the refracted direction (negative: relative to the normal on the incident side)
    and the signs of the reflected amplitudes (their phase shifts, 0 or pi, as cosines). Total internal
    reflection: (1, 1), 0 and (1, 1)."""
    e2 = eta * eta - (1.0 - cos_i * cos_i)
    if e2 <= 0.0:
        return 1.0, 1.0, 0.0, 1.0, 1.0
    ci = abs(cos_i)
    ct = -math.sqrt(e2) / eta
    rs = (ci + eta * ct) / (ci - eta * ct)
    rp = (ct + eta * ci) / (eta * ci - ct)
    return rs * rs, rp * rp, ct, 1.0 if rs >= 0.0 else -1.0, 1.0 if rp >= 0.0 else -1.0


@njit(**JIT)
def clip01(x):
    """np.clip(x, 0, 1): NaN stays NaN."""
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@njit(**JIT)
def schlick(m5, f0):
    return f0 + (1.0 - f0) * m5


@njit(inline="always", **JIT)
def f82(m5, s, mu, f0, b):
    """Cycles' F82-Tint metal (fresnel_f82, kernel/closure/bsdf_util.h; Kutz et al., "Novel aspects
    of the Adobe Standard Material"): Schlick from f0 less b mu s^6, s = 1 - mu, m5 = s^5, kept in
    [0, 1]; Schlick's own value where b is 0 (f0 in [0, 1]). Here for the film's conductor; optics
    calls it too (it imports this module, not the other way round)."""
    return clip01(schlick(m5, f0) - b * mu * m5 * s)


@njit(**JIT)
def _f82(mu, f0, b):
    s = clip01(1.0 - mu)
    return f82(s * s * s * s * s, s, mu, f0, b)


@njit(inline="always", **JIT)
def _f82_b(f0, f82):
    """The F82 model's B that gives reflectance f82 at cos 1/7."""
    f = 6.0 / 7.0
    f5 = f * f * f * f * f
    return (7.0 / (f5 * f)) * (f0 + (1.0 - f0) * f5 - f82)


@njit(inline="always", **JIT)
def _conductor_polarized(cos_i, eta1, n2, k2, f82):
    """Reflectances (Rs, Rp) and phase shifts (as unit complex numbers: re, im per polarisation) of light
    in a medium of index eta1 onto a conductor of index n2 + i k2 (Born and Wolf 14.4.1, n + ik). f82 >= 0:
    the reflectances of the F82 model of that reflectance at cos 1/7 instead (the phases stay)."""
    e1s, n2s, k2s = eta1 * eta1, n2 * n2, k2 * k2
    nk2 = 2.0 * n2 * k2
    t1 = n2s - k2s - e1s * (1.0 - cos_i * cos_i)
    t2 = math.sqrt(t1 * t1 + nk2 * nk2)
    us, vs = max(0.5 * (t2 + t1), 0.0), max(0.5 * (t2 - t1), 0.0)
    u, v = math.sqrt(us), math.sqrt(vs)
    if f82 >= 0.0:
        n, ks = n2 / eta1, (k2 / eta1) ** 2
        f0 = ((n - 1.0) ** 2 + ks) / ((n + 1.0) ** 2 + ks)
        rs = _f82(cos_i, f0, _f82_b(f0, f82))
        rp = rs
    else:
        den = (eta1 * cos_i + u) ** 2 + vs
        rs = ((eta1 * cos_i - u) ** 2 + vs) / den if den != 0.0 else 0.0
        t3, t4 = (n2s - k2s) * cos_i, nk2 * cos_i
        den = (t3 + eta1 * u) ** 2 + (t4 + eta1 * v) ** 2
        rp = ((t3 - eta1 * u) ** 2 + (t4 - eta1 * v) ** 2) / den if den != 0.0 else 0.0
    re_s, im_s = -us - vs + (eta1 * cos_i) ** 2, -2.0 * eta1 * cos_i * v
    mag = math.sqrt(re_s * re_s + im_s * im_s)
    ps = (1.0, 0.0) if mag == 0.0 else (re_s / mag, im_s / mag)
    re_p = ((n2s + k2s) * cos_i) ** 2 - e1s * (us + vs)
    im_p = 2.0 * eta1 * cos_i * (nk2 * u - (n2s - k2s) * v)
    mag = math.sqrt(re_p * re_p + im_p * im_p)
    pp = (1.0, 0.0) if mag == 0.0 else (re_p / mag, im_p / mag)
    return rs, rp, ps, pp


@njit(inline="always", **JIT)
def _airy(table, c, r12, r23, opd, ph):
    """One polarisation's Airy sum for channel c: reflectances r12 (top) and r23 (bottom), optical path
    difference opd (nm) and the phase shifts' phasor ph = (re, im)."""
    t121 = 1.0 - r12
    r123 = r12 * r23
    s123 = math.sqrt(r123)
    rs = t121 * t121 * r23 / (1.0 - r123)
    r = rs + r12
    cm = rs - t121
    a_re, a_im = ph
    for m in range(1, ORDERS + 1):
        cm *= s123
        x = 2.0 * math.pi * m * opd / TABLE_SPAN
        s_re, s_im = _lookup(table, c, x), _lookup(table, c + 3, x)
        r += cm * 2.0 * (a_re * s_re + a_im * s_im)
        a_re, a_im = a_re * ph[0] - a_im * ph[1], a_re * ph[1] + a_im * ph[0]
    return r


@njit(**JIT)
def iridescence1(table, c, thickness, film_ior, cos_i, sub_n, sub_k, f82, conductor):
    """Cycles' reflectance of channel c (0-2) of a film of thickness (nm) and index film_ior (both
    relative to the medium the light comes from, index 1) over a substrate of index sub_n (a dielectric)
    or sub_n + i sub_k (conductor; f82 >= 0: its F82 model's reflectance at cos 1/7, as Cycles' F82-Tint
    metals), at incidence cosine cos_i >= 0. 1 where the light cannot enter the film or leave it into the
    substrate (total internal reflection)."""
    if thickness < 1.0:  # under 1 nm the wave optics fade out: the film's index towards the medium's
        s = min(max(thickness, 0.0), 1.0)
        film_ior = 1.0 + (film_ior - 1.0) * (s * s * (3.0 - 2.0 * s))
    r12s, r12p, cos2, ph12s, ph12p = _dielectric_polarized(cos_i, film_ior)
    if r12s == 1.0 and r12p == 1.0:
        return 1.0
    if conductor:
        r23s, r23p, ps, pp = _conductor_polarized(-cos2, film_ior, sub_n, sub_k, f82)
    else:
        r23s, r23p, _, s23, p23 = _dielectric_polarized(-cos2, sub_n / film_ior)
        if r23s == 1.0 and r23p == 1.0:
            return 1.0
        ps, pp = (s23, 0.0), (p23, 0.0)
    opd = -2.0 * film_ior * thickness * cos2
    rs = _airy(table, c, r12s, r23s, opd, (-ph12s * ps[0], -ph12s * ps[1]))
    rp = _airy(table, c, r12p, r23p, opd, (-ph12p * pp[0], -ph12p * pp[1]))
    return min(max(0.5 * (rs + rp), 0.0), 1.0)


@njit(**JIT)
def dielectric_film1(thickness, film_ior, cos_i, eta):
    """The RGB reflectance of a glass (or a dielectric coat) of index eta under a film: cos_i = w . n, its
    sign the side (eta = n_inside / n_outside, n pointing out); from inside, the film and the outside seen
    relative to the glass (Cycles' adjust_thin_film_ior_at_backface)."""
    if cos_i < 0.0:
        film_ior, eta = film_ior / eta, 1.0 / eta
    ci = min(abs(cos_i), 1.0)
    # the channel as an int64: a constant would compile iridescence1 once per channel
    return (iridescence1(TABLE, np.int64(0), thickness, film_ior, ci, eta, 0.0, -1.0, False),
            iridescence1(TABLE, np.int64(1), thickness, film_ior, ci, eta, 0.0, -1.0, False),
            iridescence1(TABLE, np.int64(2), thickness, film_ior, ci, eta, 0.0, -1.0, False))


@njit(inline="always", **JIT)
def _gulbrandsen(f0, g):
    """n and k of a conductor whose reflectance is f0 at normal incidence and g its edge tint (Gulbrandsen
    2014, "Artist Friendly Metallic Fresnel"; Cycles reads F0 and the F82 reflectance as r and g)."""
    r = min(f0, 0.999)
    sr = math.sqrt(r)
    n = (1.0 + sr) / (1.0 - sr) * (1.0 - g) + (1.0 - r) / (1.0 + r) * g
    x = (r * (n + 1.0) ** 2 - (n - 1.0) ** 2) / (1.0 - r)
    return n, math.sqrt(x) if x > 0.0 else 0.0


@njit(**LANES)
def f82_film1(thickness, film_ior, mu, f0, b):
    """The RGB reflectance of Cycles' F82-Tint metal (F0 f0, B b, 3-tuples) under a film, at incidence
    cosine mu in [0, 1]: its n and k estimated from F0 and its reflectance at cos 1/7, the film over that
    conductor with the F82 model's reflectances."""
    return (_f82_film_channel(np.int64(0), thickness, film_ior, mu, f0[0], b[0]),
            _f82_film_channel(np.int64(1), thickness, film_ior, mu, f0[1], b[1]),
            _f82_film_channel(np.int64(2), thickness, film_ior, mu, f0[2], b[2]))


@njit(**JIT)
def _f82_film_channel(c, thickness, film_ior, mu, f0, b):
    """f82_film1's reflectance in colour channel c (F0 f0, B b: that channel's)."""
    g = _f82(1.0 / 7.0, f0, b)
    n, k = _gulbrandsen(f0, g)
    return iridescence1(TABLE, c, thickness, film_ior, mu, n, k, g, True)


@njit(**JIT)
def conductor_film1(thickness, film_ior, mu, nk):
    """The RGB reflectance of a physical conductor (index nk[c] + i nk[c + 3]) under a film, at incidence
    cosine mu in [0, 1]."""
    return (iridescence1(TABLE, np.int64(0), thickness, film_ior, mu, nk[0], nk[3], -1.0, True),
            iridescence1(TABLE, np.int64(1), thickness, film_ior, mu, nk[1], nk[4], -1.0, True),
            iridescence1(TABLE, np.int64(2), thickness, film_ior, mu, nk[2], nk[5], -1.0, True))
