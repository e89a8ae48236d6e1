"""Cycles is the judge of our radiometry (issue 2).

tests/data/cycles_mirror_* hold a converged Cycles render of
sample_blends/mirror.blend with caustics on and off in two halves (seeds 1 and 2,
8192 spp each, every "off" render with its "on" render's seed), made by ``python
tools/cycles_reference.py sample_blends/mirror.blend --spp 16384 --out
tests/data/cycles_mirror``. Cycles' caustic component is on - off; the scene lights
the floor only through the mirror, so that is the caustic alone. Our layer must match it within 3% in mean over the caustic
region, and pixel by pixel within the two estimates' combined noise.

The region is chosen on one Cycles seed and the means are taken on the other:
choosing pixels by thresholding the very image one averages keeps the pixels
that happen to be noisy-high and biased Cycles' mean up by 2.4% (measured).
"""
import math

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.cli.inputs import load_input
from smbs_addon.baking.result import caustic_region
from smbs_addon.baking.convergence import box5
from smbs_addon.io.exr import read_exr

from testkit import ROOT

DATA = ROOT / "tests" / "data"


def _load(name):
    on_a = read_exr(DATA / f"cycles_{name}_on_a.exr")[0][..., :3]
    on_b = read_exr(DATA / f"cycles_{name}_on_b.exr")[0][..., :3]
    off_a = read_exr(DATA / f"cycles_{name}_off_a.exr")[0][..., :3]
    off_b = read_exr(DATA / f"cycles_{name}_off_b.exr")[0][..., :3]
    region = caustic_region(on_a - off_a)  # chosen on seed a ...
    caustic_b = (on_b - off_b).mean(axis=2)  # ... judged on seed b
    # per-pixel variance of one half is (a - b)^2 / 2, a one-degree-of-freedom
    # estimate; averaged over 5 x 5 neighbours it has ~25
    var = box5((((on_a - off_a) - (on_b - off_b)) ** 2).mean(axis=2) / 2.0)
    return caustic_b, var, region, (on_a.mean(axis=2), on_b.mean(axis=2))


def _mean_against_cycles(res, cyc, cyc_var, region, noise):
    """Our region mean relative to Cycles', once both are precise enough to judge."""
    m_ours, se_ours = res.region_mean(region)
    m_cyc = cyc[region].mean()
    # Cycles' pixels are independent (each filter-importance sample belongs to one pixel)
    se_cyc = math.sqrt(cyc_var[region].sum()) / region.sum()
    assert se_ours < noise * m_cyc and se_cyc < noise * m_cyc, (se_ours / m_cyc, se_cyc / m_cyc)
    return m_ours / m_cyc - 1


@pytest.fixture(scope="module")
def cycles():
    return _load("mirror")


@pytest.fixture(scope="module")
def scene():
    return load_input(str(ROOT / "sample_blends" / "mirror.blend"), warn=lambda m: None)


@pytest.mark.parametrize("method,spp", [("reference", 16), ("smbs", 8)])
def test_mirror_layer_matches_cycles(cycles, scene, method, spp):
    """The mean within 3% once both are precise to 0.5% (SMBS at 4 spp: 0.27-0.61% over 32 seeds,
    a quarter of them too noisy to judge; 8 spp) and at most 2% of the pixels beyond 3 sigma."""
    cyc, cyc_var, region, (a, b) = cycles
    res = bake(scene, BakeSettings(method=method, spp=spp, seed=1))
    ours = res.image.mean(axis=2)
    rel = _mean_against_cycles(res, cyc, cyc_var, region, noise=0.005)
    assert abs(rel) < 0.03, f"{method}: {rel:+.2%} from Cycles over {region.sum()} caustic pixels"
    # pixel by pixel: differences against the combined standard error
    z = (ours - cyc)[region] / np.sqrt(res.variance.mean(axis=2)[region] + cyc_var[region] + 1e-12)
    beyond = np.mean(np.abs(z) > 3)
    assert beyond < 0.02, f"{beyond:.2%} of pixels beyond 3 sigma (a normal distribution gives 0.27%)"
    print(f"{method}: {rel:+.2%} over {region.sum()} px, {beyond:.2%} beyond 3 sigma, median |z| {np.median(np.abs(z)):.2f}")


def test_glass_ball_layer_matches_cycles():
    """sample_blends/glass_spot.blend: a glass ball (IOR 1.45) under a soft-falloff
    spot light whose cone is narrower than the ball, so the floor is lit only
    through it (Cycles reference: 2 x 8192 spp, made like the mirror's). Checks
    the refraction chain, Fresnel, the spot mask and soft falloff against Cycles."""
    cyc, cyc_var, region, _ = _load("glass_spot")
    scene = load_input(str(ROOT / "sample_blends" / "glass_spot.blend"), warn=lambda m: None)
    res = bake(scene, BakeSettings(method="reference", spp=64, seed=1))
    rel = _mean_against_cycles(res, cyc, cyc_var, region, noise=0.01)
    assert abs(rel) < 0.03, f"{rel:+.2%} from Cycles over {region.sum()} caustic pixels"


@pytest.mark.parametrize("method", ["sms", "smbs"])
def test_glass_ball_under_a_spot_walked_matches_cycles_pixel_by_pixel(method):
    """The walks on glass_spot.blend (the spot's cone cuts through the ball and the light has a
    radius of 0.3, so where the cone is tested decides the caustic's shape): the mean within 3%
    and the pixels within the combined noise, |z| with a median under 0.85 (0.67 for a normal;
    measured 0.68-0.71) and at most 5% beyond 3 sigma (measured 1.8-2.1%). With the cone tested
    on the direction from the light's centre the mean was 1.5-2.5% high but the median |z| was
    2.7 and 45% of the pixels lay beyond 3 sigma (too bright 4-8 px from the focus, 3-9x too dark
    11-20 px out)."""
    cyc, cyc_var, region, _ = _load("glass_spot")
    scene = load_input(str(ROOT / "sample_blends" / "glass_spot.blend"), warn=lambda m: None)
    res = bake(scene, BakeSettings(method=method, spp=16, seed=1))
    rel = _mean_against_cycles(res, cyc, cyc_var, region, noise=0.015)
    assert abs(rel) < 0.03, f"{method}: {rel:+.2%} from Cycles over {region.sum()} caustic pixels"
    z = np.abs((res.image.mean(axis=2) - cyc)[region]) / np.sqrt(res.variance.mean(axis=2)[region]
                                                                  + cyc_var[region] + 1e-12)
    assert np.median(z) < 0.85 and np.mean(z > 3) < 0.05, (np.median(z), np.mean(z > 3))


def test_glass_sphere_final_image_matches_cycles():
    """sample_blends/glass_sphere.blend: a glass ball under an area light that also lights
    the floor (Cycles reference 2 x 8192 spp on and off, made like the mirror's). The
    final image, Cycles without caustics plus our layer (the compositor's sum is checked
    exactly in test_addon_roundtrip), must match Cycles with caustics within 5% over the
    caustic region, baked with the defaults an artist gets (SMBS, walks plus the photon
    hand-off). Cycles' caustic also holds light the layer leaves out by definition
    (floor -> ball -> floor, and paths with inner reflections), which this scene keeps
    small by lifting the ball 0.5 above the floor: with the ball 0.1 above it, the
    caustic alone was 8% under Cycles' while the final image was 3% under. Measured
    here: final image -1.5%, caustic alone -1.6%."""
    cyc, cyc_var, region, _ = _load("glass_sphere")
    off = read_exr(DATA / "cycles_glass_sphere_off_b.exr")[0][..., :3].mean(axis=2)
    on_b = read_exr(DATA / "cycles_glass_sphere_on_b.exr")[0][..., :3].mean(axis=2)
    scene = load_input(str(ROOT / "sample_blends" / "glass_sphere.blend"), warn=lambda m: None)
    res = bake(scene, BakeSettings(method="smbs", spp=8, seed=1))
    assert res.stats["method"] == "smbs" and res.stats["lights"]["Light"]["handoff"]["handoff_paths"] > 0
    final = off + res.image.mean(axis=2)
    rel_final = final[region].mean() / on_b[region].mean() - 1
    rel_caustic = _mean_against_cycles(res, cyc, cyc_var, region, noise=0.02)
    print(f"final image {rel_final:+.2%}, caustic alone {rel_caustic:+.2%} from Cycles over {region.sum()} px")
    assert abs(rel_final) < 0.05, f"final image {rel_final:+.2%} from Cycles with caustics"
    assert abs(rel_caustic) < 0.04, f"caustic {rel_caustic:+.2%} from Cycles' on - off"
