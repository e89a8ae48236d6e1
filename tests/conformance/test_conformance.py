"""The fast subset of the conformance suite: our layer against Cycles' own caustics.

Each scene (testkit/conformance_scenes.py) is built with the bpy module and exported the
way the add-on exports; its reference is Cycles' caustic component (caustics on minus off, two
independent halves, tests/data/conformance/). The judge (testkit/conformance.py) compares the
means over the caustic region, chosen on one half of the reference and averaged on the other,
and passes within 3% + 3 sigma (our standard error from the independent batches and the
reference's from its halves combined). The whole suite, every scene x method, is
``bench/conformance.py`` (results in bench/results/conformance.md).
"""
import numpy as np
import pytest

from smbs_addon import BakeSettings, bake
from testkit import conformance as conf

pytestmark = pytest.mark.bpy

# (scene, method, spp): a few seconds each on 2 cores, covering the light tracer and the walks,
# a receiver seen directly, in a mirror and through water, and Cycles' MNEE as the judge
CASES = [
    ("mirror_point_hard", "reference", 64),
    ("mirror_point_hard", "sms", 4),
    ("mirror_point_hard", "smbs", 4),
    # Light Linking: a lamp lighting a glass ball alone, one lighting all but the ball: 1.81 of Cycles when ignored
    ("linked_lamps", "reference", 256),
    ("linked_lamps", "sms", 4),
    # Shadow Linking: a plate between the bulb and the ball that does not shadow the bulb: 0.002 of Cycles when ignored
    ("shadow_linked_ball", "reference", 256),
    ("shadow_linked_ball", "smbs", 4),
    # the same with a mesh light: 0.89 of Cycles when a shadow ray past the plate met the light's own triangles
    ("shadow_linked_glow", "smbs", 16),
    # a Principled mirror of Metallic 0.5 mixed at 0.5 with a diffuse: 1.12 of Cycles with its coat at 1 - 0.5 x 0.5
    ("mix_alloy_mirror", "reference", 256),
    # thin films: a glass ball's (1.31 of Cycles with the film ignored), a Principled mirror's (1.03)
    ("film_ball", "smbs", 16),
    ("film_alloy_mirror", "sms", 16),
    # a Principled glass's Specular Tint 4 / 1 / 0: red 1.29 and blue 0.93 of Cycles with the tint ignored
    ("spec_tint_ball", "smbs", 16),
    ("lens_area", "reference", 32),
    ("sphere_refraction_spot", "reference", 32),
    ("sphere_refraction_spot", "smbs", 4),
    ("pool_sun4", "smbs", 4),
    # issue 61's pool at 160 x 120: auto bakes it by the straight-line walk alone (MNEE's way), the
    # pilot bounding the light of the other solutions below 0.05%
    ("pool_sun", "auto", 8),
    # ... and under a dim sky with a bright disc of 5 degrees, where the pilot meets other solutions
    # (bound 2.1%) and auto stays unbiased: anchored SMBS
    ("pool_hdri", "smbs", 16),
    # an area light's spread of 30 degrees: 0.08 of Cycles before the soft-box factor
    ("mirror_spread30", "reference", 256),
    ("mirror_spread30", "sms", 4),
    ("water_flat_sun0", "smbs", 4),
    ("cube_white_glossy1", "reference", 256),  # Light Paths: 0.86 of the caustic without the limit
    # the reflection off a bevelled glass cube's outside: 0.74 without Cycles' Bump Map Correction
    ("cube_grey_reflect", "reference", 2048),
    # a floor of Blender's default material (Principled BSDF) seen at a slant: 1.15 of Cycles before
    # its glossy layer took its share off the diffuse (layer.py)
    ("principled_floor", "reference", 256),
    ("principled_floor", "smbs", 4),
    # a Diffuse BSDF of Roughness 1 (Cycles' Oren-Nayar): 1.066 of Cycles as Lambert
    ("rough_floor", "reference", 1024),
    # a Principled mirror of Metallic 0.7: 1.44 of Cycles as a whole metal
    ("mirror_alloy", "reference", 256),
    # a clear coat (Coat Weight 1) over the default material: 1.21 of Cycles when ignored
    ("coated_floor", "reference", 512),
    # a Checker Texture on the default material's Base Color, composited with the render's Diffuse Color
    # pass: 0.66 of Cycles with the texture's mean colour alone (0.967 now: the colour of the floor seen through the
    # ball and of the coat's sampling share are the mean's)
    ("checker_floor", "reference", 512),
    # a glass ball with a Volume Absorption (0.15/0.6/1.05 per metre): 1.63 of Cycles unabsorbed
    ("tinted_ball", "reference", 256),
    ("tinted_ball", "smbs", 4),
    # a world of constant colour, the only light: left to Cycles (and its caustics kept on) before it
    # was a light of the layer (S.WORLD)
    ("world_ball", "reference", 64),
    # a grey world beside a bulb, both through a mirror
    ("world_mirror_bulb", "smbs", 4),
    # an HDRI (a sky and a 4-degree sun) turned 40 degrees by a Mapping node
    ("hdri_ball", "reference", 512),
    # Mix Shaders: a ball of glass at 0.75 over a dark diffuse cast nothing (a mix was a diffuse stand-in),
    # a floor of Diffuse and Glossy at 0.25 read 1.33 of Cycles
    ("mix_frosted_ball", "reference", 256),
    ("mix_frosted_ball", "smbs", 4),
    ("mix_floor", "reference", 256),
    # a Mix Shader by a Fresnel node: the old glass (Refraction and Glossy) cast nothing, the old coated
    # floor (Diffuse and Glossy) read 1.19 of Cycles
    ("fresnel_glass_ball", "reference", 256),
    ("fresnel_floor", "reference", 256),
    # the fake-shadow trick (Glass and Transparent by Light Path's Is Shadow Ray) cast nothing
    ("fake_shadow_ball", "smbs", 4),
    # rough casters (rough.py), baked smooth before: 1.26 of Cycles for the default glass, 1.14 for the
    # default metal; as GGX without Cycles' energy compensation 0.87 and 0.85. The walks leave them to
    # the photons (MNEE too)
    ("rough_glass_ball", "reference", 256),
    ("rough_glass_ggx", "smbs", 256),
    ("rough_mirror", "mnee", 256),
    ("rough_tinted_mirror", "reference", 256),
    ("rough_tinted_glass", "reference", 256),
    ("rough_pool_sun", "reference", 256),
    # a bumped floor seen through water (the view of the bumped receivers alone, looked up where the floor's
    # point projects): 1.094 of Cycles with the smooth normal
    ("pool_bumped_floor", "smbs", 4),
    # Ray Visibility: a light glossy rays do not see, one transmission rays do not see, a ball diffuse rays
    # do not see (test_ray_visibility_leaves_out_what_cycles_leaves_out: SMS)
    ("ray_visibility", "reference", 256),
    # a glass ball and a card camera rays do not meet (test_ray_visibility_leaves_out_what_cycles_leaves_out)
    ("hidden_ball", "reference", 256),
    # a card glossy rays and a ball transmission rays do not meet (the same test)
    ("hidden_kinds", "reference", 256),
    # mesh lights (an Emission shader's object): no light at all to the layer before; a panel whose back the
    # ball sees, and a closed glowing ball over a mirror (0.655 of Cycles when the shadow ray to a point on
    # the ball met the ball itself)
    ("mesh_light_ball", "reference", 256),
    ("mesh_light_ball", "smbs", 4),
    ("mesh_light_mirror", "sms", 16),
    # a Principled BSDF's Emission on a receiving panel (left out, warned, before)
    ("principled_glow_ball", "reference", 256),
    # the Metallic BSDF (Blender 4.3 on), 'not supported; treated as diffuse' before (no caustic): its F82
    # mode with an Edge Tint, and its Physical Conductor mode (Schlick from its head-on reflectance: 1.05
    # of Cycles for the light tracer, against 1.013)
    ("metallic_edge_ring", "smbs", 16),
    ("conductor_ring", "sms", 16),
]


def _judge(name, method, spp, seed=1):
    res = bake(conf.scene_arrays(name), BakeSettings(method=method, spp=spp, seed=seed))
    ref = conf.load_reference(name)
    return res, conf.judge(conf.composed_luminance(res, ref.get("diffcol")), ref)


@pytest.mark.parametrize("name,method,spp", CASES, ids=[f"{n}-{m}" for n, m, _ in CASES])
def test_matches_cycles(name, method, spp):
    res, j = _judge(name, method, spp)
    assert np.isfinite(res.image).all()
    assert j["sigma"] < 0.05, f"too noisy to judge: sigma {j['sigma']:.1%}"
    assert j["within"], (f"{name} / {method}: {j['ratio']:.3f} of Cycles, 3 sigma = {3 * j['sigma']:.3f} "
                         f"(ours {j['se_ours']:.2%}, reference {j['se_ref']:.2%})")


@pytest.mark.parametrize("name", ["bumped_pool_sun", "normal_mapped_pool_sun"])
def test_waves_of_a_bump_or_a_normal_map_on_water_cast_cycles_caustic_network(name):
    """Flat water whose waves are a Bump node of a Noise Texture, or a Normal Map node of an image
    (bump.py). The light the water lets through is the flat water's, so the judge's mean alone cannot
    tell (bumped_pool_sun unbumped, the export's way before: 1.029 of Cycles, within); the pattern over
    6 x 6 pixel blocks can. Seed 1, SMBS 16 spp: block error 0.030 and 0.030 (the reference's own noise
    taken out), correlation 0.986 and 0.993; unbumped 0.218 / -0.01 and 0.303 / 0.14, the references'
    contrast 0.21 and 0.30."""
    res, j = _judge(name, "smbs", 16)
    assert j["within"], j
    p = conf.pattern(res.batch_luminance.mean(axis=0), conf.load_reference(name))
    assert p["contrast"] > 0.15 and p["block_rmse"] < 0.07 and p["correlation"] > 0.95, p


def test_a_bumped_slab_seen_from_behind_bends_as_cycles_does():
    """bumped_slab_sun: a closed slab whose Bump node reads a Noise Texture in Object coordinates. Cycles'
    eye paths meet its top from inside, from behind, where such a bump bends the normal the other way
    (bump.py; Scene.tri_normals_back). Light tracer, 256 spp, seed 1: 0.972 of Cycles, blocks off by
    0.23 of the mean (the caustic is a small patch: the reference's contrast 2.8), correlation 0.994;
    with the front's normals from both sides, as before, 0.944, 1.61 and 0.853."""
    sc = conf.scene_arrays("bumped_slab_sun")
    ref = conf.load_reference("bumped_slab_sun")
    assert sc.tri_normals_back.shape == sc.tri_normals.shape
    for back in (True, False):
        if not back:
            sc.tri_normals_back = np.zeros((0, 3, 3))
        res = bake(sc, BakeSettings(method="reference", spp=256, seed=1))
        j = conf.judge(res.batch_luminance, ref)
        p = conf.pattern(res.batch_luminance.mean(axis=0), ref)
        if back:
            assert j["within"] and p["block_rmse"] < 0.5 and p["correlation"] > 0.98, (j, p)
        else:
            assert p["block_rmse"] > 1.0 and p["correlation"] < 0.9, p


def test_a_metals_edge_tint_colours_its_caustic_as_cycles():
    """metallic_edge_ring's Edge Tint (0.9, 0.5, 0.15) darkens the blue of the ring's grazing reflections
    most (Cycles' F82-Tint). The judge's mean over the channels cannot tell it from Schlick (1.05 against
    1.02); the caustic's blue over its red, ours over Cycles', can. SMBS 64 spp, seed 1: 1.017 (over seeds
    1-5 at 8 spp, standard deviation 0.028, so ~0.01 here); plain Schlick from the same F0: 1.155."""
    import dataclasses

    from smbs_addon.scene import arrays as S

    name = "metallic_edge_ring"
    sc, ref = conf.scene_arrays(name), conf.load_reference(name)
    truth = 0.5 * (ref["a"] + ref["b"])
    region = conf.region_of(truth.mean(axis=2))
    m = int(np.flatnonzero(sc.mat_kind == S.CONDUCTOR)[0])
    assert sc.mat_fresnel[m] == S.FRESNEL_SCHLICK and sc.mat_metal[m, :3].max() > 0
    schlick = dataclasses.replace(sc, mat_metal=np.zeros((0, 6)))
    tint = []
    for s in (sc, schlick):
        r = bake(s, BakeSettings(method="smbs", spp=64, seed=1)).image[region].mean(axis=0) / truth[region].mean(axis=0)
        tint.append(r[2] / r[0])
    assert abs(tint[0] - 1.0) < 0.05 and tint[1] > 1.09, tint


def _tint_against_bare(name, spp, bare, plain, within):
    """Bake scene `name` (light tracer, seed 1) as exported and with `plain` replacing some of its arrays (an
    effect taken away); per channel over the reference's caustic region, ours over Cycles': as exported,
    each channel within `within` of the judge's luminance ratio and the judge within, blue over red within
    0.04 of 1; taken away, blue over red within 0.04 of `bare`."""
    import dataclasses

    sc, ref = conf.scene_arrays(name), conf.load_reference(name)
    truth = 0.5 * (ref["a"] + ref["b"])
    region = conf.region_of(truth.mean(axis=2))
    tints = []
    for s in (sc, dataclasses.replace(sc, **plain)):
        res = bake(s, BakeSettings(method="reference", spp=spp, seed=1))
        ch = res.image[region].mean(axis=0) / truth[region].mean(axis=0)
        tints.append(ch[2] / ch[0])
        if s is sc:
            j = conf.judge(conf.composed_luminance(res, ref.get("diffcol")), ref)
            assert j["within"] and np.abs(ch / j["ratio"] - 1.0).max() < within, (j, ch)
    assert abs(tints[0] - 1.0) < 0.04 and abs(tints[1] - bare) < 0.04, tints
    return sc


@pytest.mark.parametrize("name,spp,bare", [("film_ball", 256, 1.23), ("anodized_ring", 128, 0.47),
                                           ("film_alloy_mirror", 128, 0.94)])
def test_a_thin_film_colours_its_caustic_as_cycles(name, spp, bare):
    """A thin film's iridescence (thinfilm.py), per channel: the caustic's mean over the reference's
    caustic region, ours over Cycles', each channel within 5% of the luminance's ratio, the judge within;
    with the film ignored (as before), the blue over the red moves by `bare` (the film_ball's ball lets
    1.31 of Cycles' light through, 1.15 red and 1.42 blue; the anodised ring, 1.73; film_alloy_mirror's
    metal and coat, 1.03). Light tracer, seed 1: film_ball 0.998 (channels 0.997, 1.000, 0.997),
    anodized_ring 1.008 (0.990, 1.008, 1.016), film_alloy_mirror 0.976 (0.978, 0.975, 0.974)."""
    sc = _tint_against_bare(name, spp, bare, dict(mat_film=np.zeros((0, 2))), 0.05)
    assert sc.mat_film.size and sc.mat_film[:, 0].max() > 100


def test_a_glass_specular_tint_colours_its_caustic_as_cycles():
    """spec_tint_ball: a Principled glass ball of Specular Tint 4 / 1 / 0 (f0 = 0.16 / 0.04 / 0, optics.tinted_glass),
    each channel within 3% of the luminance's ratio; with the tint ignored (as before: white), red comes out
    1.29 of Cycles and blue 0.93 (blue over red 0.725). Light tracer 256 spp, seed 1: 0.993 (channels 0.991,
    0.994, 0.994); SMBS 16 spp 1.014 (1.012, 1.015, 1.016)."""
    sc = _tint_against_bare("spec_tint_ball", 256, 0.725, dict(mat_metal=np.zeros((0, 6))), 0.03)
    assert sc.mat_metal.size and sc.mat_metal[:, 0].max() > 2.9


def test_the_judge_sees_a_world_map_turned_the_wrong_way():
    """hdri_ball's map looked up turned the other way (the Mapping node's turn transposed), or not
    turned: its sun's caustic lands elsewhere and the judge says so. Seed 1, 512 spp: 1.004 as
    exported, 1.32 turned the other way, 1.157 not turned (3 sigma 0.02-0.03)."""
    sc = conf.scene_arrays("hdri_ball")
    ref = conf.load_reference("hdri_ball")
    for rotation in (sc.world_map_rotation.T.copy(), np.eye(3)):
        sc.world_map_rotation = rotation
        j = conf.judge(conf.composed_luminance(bake(sc, BakeSettings(method="reference", spp=256, seed=1)), None), ref)
        assert not j["within"] and j["ratio"] > 1.1, j


@pytest.mark.parametrize("method,spp", [("reference", 128), ("sms", 4), ("smbs", 4)])
def test_an_absorbing_ball_seen_through_and_directly_matches_cycles(method, spp):
    """absorbing_ball_area (issue 62): a grey Glass BSDF ball (Color 0.8) with a Volume Absorption (0.12 / 0.54 /
    1.02 per metre) under two area lights; the camera sees the key light's focus through the ball (its eye paths
    absorbed in the ball as well as its light, gathered by cosine sampling from the floor) and the side light's
    focus directly. Judged apart, as bench/conformance_split.py does (view_masks): each part within 3% + 3 sigma,
    and in the part seen through the ball each channel within 3% of the channels' mean (an eye path absorbed over
    a wrong length, or tinted by the Glass colour at a wrong event, moves blue against red there). Seed 1 against
    16,384 spp (0.11%): light tracer 128 spp 1.014 directly / 0.992 through, SMS 4 spp 1.006 / 1.000, SMBS 4 spp
    0.992 / 1.000, every channel within 0.3% of the others (seeds 2, 3: 0.99-1.02). The error issue 62 reported
    through such a ball (a colour-neutral 0.76 and 0.2 m more of the medium: red 0.74, blue 0.60) fails both
    checks; with the absorption ignored (the export before 3f5ba5c) the light tracer reads 1.69 directly and 2.43
    through (blue 8.2 times Cycles')."""
    import dataclasses

    name = "absorbing_ball_area"
    sc, ref = conf.scene_arrays(name), conf.load_reference(name)
    direct, through = conf.view_masks(sc)
    truth = 0.5 * (ref["a"] + ref["b"])
    region = conf.region_of(truth.mean(axis=2))
    seen = region & through
    assert (region & direct).sum() > 100 and seen.sum() > 500, ((region & direct).sum(), seen.sum())

    def check(s):
        res = bake(s, BakeSettings(method=method, spp=spp, seed=1))
        parts = {part: conf.judge(res.batch_luminance, ref, m) for part, m in (("direct", direct), ("through", through))}
        return res, parts, res.image[seen].mean(axis=0) / truth[seen].mean(axis=0)

    res, parts, ch = check(sc)
    for part, j in parts.items():
        assert j["sigma"] < 0.05, f"{part}: too noisy to judge: sigma {j['sigma']:.1%}"
        assert j["within"], (f"{name} / {method}, seen {part}: {j['ratio']:.3f} of Cycles, 3 sigma = {3 * j['sigma']:.3f} "
                             f"(ours {j['se_ours']:.2%}, reference {j['se_ref']:.2%})")
    assert np.abs(ch / ch.mean() - 1.0).max() < 0.03, ch
    # the judge and the channel check see the error issue 62 reported at the pixels seen through the ball
    wrong = 0.76 * np.exp(-sc.mat_absorb[sc.mat_absorb.max(axis=1) > 0][0] * 0.2)
    dimmed = np.where(through[None], wrong.mean(), 1.0) * res.batch_luminance
    assert not conf.judge(dimmed.astype(np.float32), ref, through)["within"]
    assert np.abs(ch * wrong / (ch * wrong).mean() - 1.0).max() > 0.03
    if method == "reference":  # and a bake that leaves the absorption out
        _, parts, ch = check(dataclasses.replace(sc, mat_absorb=np.zeros((0, 3))))
        assert not parts["direct"]["within"] and not parts["through"]["within"], parts
        assert ch[2] / ch[0] > 2.0, ch


def test_mnee_is_never_brighter_than_cycles():
    """MNEE finds one solution per light sample: on a sphere (two solutions or more) it is
    biased low, and it must never be high. At 32 spp: MNEE's fireflies on the sphere leave its
    sigma at 0.04-0.15 over seeds 1-4 at 8 spp (0.016-0.056 at 32; ratios 0.30-0.40 throughout)."""
    _, j = _judge("sphere_refraction_spot", "mnee", 32)
    assert j["ratio"] < 0.9 and j["sigma"] < 0.05, j
    _, j = _judge("water_flat_sun0", "mnee", 8)  # one solution: exact
    assert abs(j["ratio"] - 1.0) <= 0.03 + 3 * j["sigma"], j


def test_the_judge_sees_a_five_percent_error():
    """The same bake scaled by 0.95 fails the judge where the noise is small: the suite's
    tolerance is tight enough to catch the errors it is there for. At 16 spp: our sigma at 8 spp
    was 0.0016-0.0037 over 24 seeds (mean 0.0026), too near the 0.0033 this needs."""
    res, j = _judge("water_flat_sun0", "mnee", 16)
    assert j["within"] and 3 * j["sigma"] < 0.01
    scaled = conf.judge(res.batch_luminance * 0.95, conf.load_reference("water_flat_sun0"))
    assert not scaled["within"]
    assert scaled["ratio"] == pytest.approx(0.95 * j["ratio"], rel=1e-6)


def test_the_judge_takes_pixels_seen_directly_and_in_the_mirror_apart():
    """view_masks splits the image into pixels whose primary rays all meet the floor and pixels
    whose rays all meet the mirror; judge(mask=) reads only the region's pixels of one kind:
    scaling our bake by 0.9 in the mirror's pixels alone moves that judgement by exactly 0.9 and
    leaves the other's unchanged."""
    name = "mirror_point_hard"
    sc = conf.scene_arrays(name)
    direct, through = conf.view_masks(sc)
    assert not (direct & through).any()
    assert direct.sum() > 100 and through.sum() > 100, (direct.sum(), through.sum())
    res, whole = _judge(name, "sms", 4)
    ref = conf.load_reference(name)
    jd, jt = conf.judge(res.batch_luminance, ref, direct), conf.judge(res.batch_luminance, ref, through)
    assert jd["pixels"] > 20 and jt["pixels"] > 20, (jd["pixels"], jt["pixels"])
    dimmed = (np.where(through, 0.9, 1.0)[None] * res.batch_luminance).astype(res.batch_luminance.dtype)
    assert conf.judge(dimmed, ref, direct)["ratio"] == jd["ratio"]
    assert conf.judge(dimmed, ref, through)["ratio"] == pytest.approx(0.9 * jt["ratio"], rel=1e-6)
    assert conf.judge(dimmed, ref)["ratio"] < whole["ratio"]


def test_an_off_render_of_the_same_seed_cancels_light_seen_through_glass(tmp_path):
    """Why each half of a reference is an "on" render less an "off" render of the same seed
    (tools/conformance.add_round): Cycles draws the same random numbers for a camera path until
    its first diffuse vertex. With the floor of cube_grey black, all the image holds is the
    area light seen through and in the glass cube, never a diffuse vertex: on - off of one seed
    is zero in every pixel, exactly, while an "off" render of another seed differs by that
    light's noise (the noise a shared "off" render left in both halves of the old references)."""
    import bpy

    from testkit import conformance_scenes as scenes
    from testkit.cycles import read_exr_rgb, set_render

    blend = scenes.build("cube_grey", tmp_path)
    imgs = {}
    for tag, seed, caustics in (("on", 3, True), ("off", 3, False), ("off_other", 4, False)):
        bpy.ops.wm.open_mainfile(filepath=str(blend))
        floor = bpy.data.materials["Floor"].node_tree.nodes
        for node in floor:
            for socket in ("Color", "Base Color"):
                if socket in node.inputs:
                    node.inputs[socket].default_value = (0.0, 0.0, 0.0, 1.0)
        sc = bpy.context.scene
        set_render(sc, 16, seed, caustics, 2)
        sc.render.filepath = str(tmp_path / f"{tag}.exr")
        bpy.ops.render.render(write_still=True)
        imgs[tag] = read_exr_rgb(tmp_path / f"{tag}.exr").mean(axis=2)
    seen = imgs["on"] > 0  # the light's image in the cube
    assert seen.sum() > 10, seen.sum()
    assert np.array_equal(imgs["on"], imgs["off"])
    other = np.abs(imgs["off_other"] - imgs["on"])[seen].sum() / imgs["on"][seen].sum()
    print(f"{seen.sum()} pixels see the light; another seed's off differs there by {other:.0%}")
    assert other > 0.2, other


def test_light_tracers_bent_pass_covers_the_film_below_64_samples_per_batch():
    """The light tracer's bent pass (Cycles' Bump Map Correction) takes one eye sample in 64: with
    fewer than 64 samples per pixel per batch that is fewer samples than film cells, and they must
    still be spread over the whole film. They were not (eye.film_samples gave the first cells
    only), and cube_grey_reflect, where bent normals carry a quarter of the light, read 0.742 +-
    0.008 of Cycles at 256 spp in 8 batches. Here 1024 spp in 32 batches (32 per batch), seed 1:
    0.764 before the fix (a558295); since, seeds 1-3 read 0.999, 0.997, 1.010 (sigma 0.041-0.055)."""
    res = bake(conf.scene_arrays("cube_grey_reflect"), BakeSettings(method="reference", spp=1024, batches=32, seed=1))
    j = conf.judge(res.batch_luminance, conf.load_reference("cube_grey_reflect"))
    assert j["sigma"] < 0.05, j
    assert j["within"], (f"{j['ratio']:.3f} of Cycles, 3 sigma = {3 * j['sigma']:.3f}")


def test_a_bumped_floor_is_shaded_as_cycles_shades_it():
    """bumped_floor: a Diffuse BSDF floor whose Normal is a Bump node of a Noise Texture, under the
    slanted glass ball. Its caustic is shaded with the normals Cycles' camera rays meet on the floor (the
    view the export renders: Scene.view_normals) and Cycles' shadowing of a bent normal. Light tracer, 512 spp,
    seed 1: 1.000 of Cycles, per pixel over the caustic 7.8% from it (its own noise and ours; 3.6% at
    2048 spp); with the smooth normal, as before, 1.081 (outside the judge) and 24%."""
    ref = conf.load_reference("bumped_floor")
    A, B = ref["a"].mean(axis=2), ref["b"].mean(axis=2)
    truth = 0.5 * (A + B)
    region = conf.region_of(truth)
    for bumped in (True, False):
        sc = conf.scene_arrays("bumped_floor")
        assert sc.mat_view_bump.any() and sc.view_normals.size
        if not bumped:
            sc.mat_view_bump = np.zeros(0, bool)
        res = bake(sc, BakeSettings(method="reference", spp=512, seed=1))
        j = conf.judge(res.batch_luminance, ref)
        ours = res.image.mean(axis=2)
        mse = ((ours[region] - truth[region]) ** 2).mean() - ((A[region] - B[region]) ** 2 / 4.0).mean()
        per_pixel = float(np.sqrt(max(mse, 0.0)) / truth[region].mean())
        if bumped:
            assert j["within"] and per_pixel < 0.14, (j, per_pixel)
        else:
            assert not j["within"] and per_pixel > 0.18, (j, per_pixel)


@pytest.mark.parametrize("name", ["ray_visibility", "hidden_ball", "hidden_kinds"])
def test_ray_visibility_leaves_out_what_cycles_leaves_out(name):
    """ray_visibility: a bulb glossy rays do not see, a lamp transmission rays do not see, a glass ball
    diffuse rays do not see; hidden_ball: a glass ball and a card camera rays do not meet, the caustic
    seen past them; hidden_kinds: a card glossy rays do not meet between a mirror and its bulb, a glass
    ball transmission rays do not meet (Scene.light_visibility, object_visibility). SMS 4 spp, seed 1:
    0.990, 1.008 and 0.951 of Cycles over the caustic region, 0.984, 0.992 and 0.951 over the whole
    image; with every ray meeting every light and object, as the export had it before, 1.82 and 2.27
    (the mirror's light of the bulb, the ball's refraction of the lamp, the second ball's caustic), 0.000
    and 0.067 (the card hides the caustic), 0.739 and 0.744 (the card takes the mirror's light)."""
    ref = conf.load_reference(name)
    for read in (True, False):
        sc = conf.scene_arrays(name)
        assert sc.object_visibility.size
        if not read:
            sc.light_visibility, sc.object_visibility = np.zeros(0, np.int64), np.zeros(0, np.int64)
        j = conf.judge(bake(sc, BakeSettings(method="sms", spp=4, seed=1)).batch_luminance, ref)
        if read:
            assert j["within"] and abs(j["whole_image_ratio"] - 1.0) < 0.07, j
        elif name == "ray_visibility":
            assert j["ratio"] > 1.5 and j["whole_image_ratio"] > 1.8, j
        elif name == "hidden_kinds":  # the card takes the mirror's light, the ball casts through both sides
            assert j["ratio"] < 0.85, j
        else:
            assert j["ratio"] < 0.1 and j["whole_image_ratio"] < 0.2, j
