"""Receivers whose colour is a texture (Scene.mat_textured): the bake keeps, where the camera sees
them directly, their caustic per unit albedo (BakeResult.per_albedo) for the render's Diffuse
Color pass to multiply, and takes it out of the layer added as it is (BakeResult.layer)."""
from __future__ import annotations

import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from smbs_addon.scene import arrays as S
from smbs_addon.io.exr import exr_channels
from testkit import conformance as conf, scenes


def _eroded(mask, k):
    out = mask.copy()
    for _ in range(k):
        out[1:] &= out[:-1].copy()
        out[:-1] &= out[1:].copy()
        out[:, 1:] &= out[:, :-1].copy()
        out[:, :-1] &= out[:, 1:].copy()
    return out


def _textured(scene):
    floor = scene.mat_kind == S.DIFFUSE
    scene.mat_textured = floor.copy()
    return scene


@pytest.mark.parametrize("method", ["reference", "smbs", "mnee"])
def test_the_flag_splits_the_same_image(method):
    """The flag changes no estimate: the image is the same bit for bit; its textured part is the
    share of it that fell on the floor seen directly (every pixel the camera sees the floor in
    holds nothing else), and per_albedo is that part over the floor's albedo (a Lambert floor:
    the colour itself), sample by sample."""
    settings = BakeSettings(method=method, spp=2, seed=4)
    plain = bake(scenes.glass_sphere_scene(resolution=(32, 24)), settings)
    sc = _textured(scenes.glass_sphere_scene(resolution=(32, 24)))
    tex = bake(sc, settings)
    assert plain.per_albedo is None and plain.textured is None and plain.layer() is plain.image
    np.testing.assert_array_equal(tex.image, plain.image)
    albedo = sc.mat_color[sc.mat_kind == S.DIFFUSE][0]
    np.testing.assert_allclose(tex.per_albedo * albedo, tex.textured, rtol=1e-5, atol=1e-7 * tex.image.max())
    direct, through = conf.view_masks(sc)
    assert direct.sum() > 100 and through.sum() > 20
    lay = tex.layer()
    # all of it the pass's to colour (but within the pixel filter's reach of what is seen through the ball)
    assert np.abs(lay[_eroded(direct, 2)]).max() <= 1e-5 * tex.image.max()
    inner = _eroded(through, 2)  # beyond the pixel filter's reach from the floor seen directly
    assert inner.sum() > 10 and tex.textured[inner].max() == 0.0  # seen through the ball: the stand-in stays
    assert lay.min() >= -1e-5 * tex.image.max()
    share = tex.stats["textured_share"]
    assert 0.5 < share <= 1.0 + 1e-6
    np.testing.assert_allclose(share, tex.textured.mean(axis=2).sum() / tex.image.mean(axis=2).sum(), rtol=1e-5)


def test_under_a_principled_coat_the_albedo_is_what_the_coat_leaves():
    """A Principled floor (glossy coat, Roughness 0.5): each sample's albedo is the colour times
    1 - A(mu) towards the eye, as Cycles' Diffuse Color pass holds it; per_albedo times that
    pass (the colour times the coat's share at the pixel's mu) gives back the textured part
    within the spread of mu inside a pixel (0.5%)."""
    from smbs_addon.shading import coat as layer

    sc = _textured(scenes.glass_sphere_scene(resolution=(32, 24)))
    sc.mat_layer = np.zeros((len(sc.mat_kind), 8))
    sc.mat_layer[sc.mat_kind == S.DIFFUSE] = (1.5, 0.5, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0)
    r = bake(sc, BakeSettings(method="reference", spp=2, seed=2))
    direct, _ = conf.view_masks(sc)
    sel = direct & (r.textured.mean(axis=2) > 0.05 * r.textured.max())
    assert sel.sum() > 20
    ratio = r.textured[sel] / r.per_albedo[sel]  # the albedo the samples were divided by
    color = sc.mat_color[sc.mat_kind == S.DIFFUSE][0]
    tab = layer.table(sc)
    w_min, w_max = (float(layer.weight(tab, np.array([0]), np.array([mu]))[0]) for mu in (0.2, 1.0))
    assert np.all((ratio > color * w_min * 0.999) & (ratio < color * w_max * 1.001))
    assert np.ptp(ratio[:, 0]) > 1e-3  # it follows mu across the floor


def test_flags_given_as_numbers_split_the_same():
    """A scene built in code may mark textured receivers with 0/1 numbers: the same split."""
    settings = BakeSettings(method="smbs", spp=1, seed=6)
    as_bool = bake(_textured(scenes.glass_sphere_scene(resolution=(16, 12))), settings)
    sc = scenes.glass_sphere_scene(resolution=(16, 12))
    sc.mat_textured = (sc.mat_kind == S.DIFFUSE).astype(float)
    as_float = bake(sc, settings)
    np.testing.assert_array_equal(as_float.per_albedo, as_bool.per_albedo)
    np.testing.assert_array_equal(as_float.image, as_bool.image)


def test_the_exr_holds_the_layer_and_the_per_albedo_channels():
    sc = _textured(scenes.glass_sphere_scene(resolution=(16, 12)))
    r = bake(sc, BakeSettings(method="reference", spp=1, seed=1))
    from smbs_addon.cli.report import summary_lines

    assert any(line.startswith("  textured receivers: ") and "Diffuse Color pass" in line
               for line in summary_lines(r.stats))
    ch = exr_channels(r)
    assert set(ch) == {"std", "per_albedo_R", "per_albedo_G", "per_albedo_B"}
    np.testing.assert_array_equal(np.stack([ch[f"per_albedo_{c}"] for c in "RGB"], axis=2), r.per_albedo)


def test_composed_luminance_for_the_judge():
    """The conformance judge composes our batches as the compositor would: a flat Diffuse Color
    pass equal to the stand-in gives back the batches; twice that, the textured part twice."""
    sc = _textured(scenes.glass_sphere_scene(resolution=(16, 12)))
    r = bake(sc, BakeSettings(method="reference", spp=2, seed=1))
    color = sc.mat_color[sc.mat_kind == S.DIFFUSE][0]
    same = conf.composed_luminance(r, np.broadcast_to(color, r.image.shape))
    np.testing.assert_allclose(same, r.batch_luminance, rtol=1e-4, atol=1e-6 * r.image.max())
    twice = conf.composed_luminance(r, np.broadcast_to(2 * color, r.image.shape)).mean(axis=0)
    want = (r.layer() + 2 * r.textured).mean(axis=2)
    np.testing.assert_allclose(twice, want, rtol=1e-3, atol=1e-5 * r.image.max())
    with pytest.raises(ValueError, match="Diffuse Color"):
        conf.composed_luminance(r, None)
