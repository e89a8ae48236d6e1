"""Equal time on the user's scene (smbs_addon/compare.py, ``python -m smbs_addon compare``).

How many samples a method fits in its seconds depends on the machine, so these tests assert
what holds for any count: every bake is measured over one region by the same rule as the
error bar, the table's time for the same error is error^2 x seconds relative to the least,
a biased method gets no such number and says why, and a reference's own noise comes out of
the RMSE."""
import json
import math

import numpy as np
import pytest

from testkit import scenes
from smbs_addon import BakeSettings, bake
from smbs_addon.baking.compare import Reference, compare, json_report, table_lines
from smbs_addon.baking.convergence import caustic_region, relative_error
from smbs_addon.core.errors import SceneError
from smbs_addon.io.exr import write_exr
from smbs_addon.io.exr import exr_channels, exr_metadata


@pytest.fixture(scope="module")
def sphere():
    return scenes.glass_sphere_scene(resolution=(48, 36))


def test_every_method_is_measured_over_one_region_and_priced_against_the_fastest(sphere):
    rep = compare(sphere, ("reference", "sms", "mnee"), 0.3, BakeSettings(spp=8, batches=8, seed=2))
    assert [r["method"] for r in rep["rows"]] == ["reference", "sms", "mnee"] and rep["region_from"] == "bakes"
    res = rep["results"]
    region = caustic_region(sum(r.image.astype(np.float64).mean(axis=2) for r in res.values()) / 3)
    assert rep["region_pixels"] == int(region.sum()) > 0
    for row in rep["rows"]:
        r = res[row["method"]]
        assert row["batches"] == r.stats["batches_done"] >= 2 and r.stats["stopped_by"] == "time"
        assert row["spp"] == row["batches"]  # one sample per pixel per batch
        assert row["error"] == pytest.approx(relative_error(r.batch_luminance, region), rel=1e-12)
    unbiased = {row["method"]: row["error"] ** 2 * row["time_s"] for row in rep["rows"][:2]}
    for row in rep["rows"][:2]:
        assert row["time_for_same_error"] == pytest.approx(unbiased[row["method"]] / min(unbiased.values()))
        assert row["leaves_out"] == []
    mnee = rep["rows"][2]
    assert mnee["time_for_same_error"] is None and mnee["leaves_out"][0].startswith("MNEE's bias")
    lines = table_lines(rep)
    assert any(ln.startswith("| mnee |") and "biased: MNEE's bias" in ln for ln in lines)
    best = min(rep["rows"][:2], key=lambda row: row["time_for_same_error"])["method"]
    assert any(ln.startswith(f"fastest to a given noise: {best} (") for ln in lines)
    json.dumps(json_report(rep), allow_nan=False)


def test_a_reference_bakes_noise_comes_out_of_the_rmse(sphere, tmp_path):
    """Against a long light-tracing bake written as our EXR (its std channel read back as its
    noise), the RMSE is what one computes by hand with that noise taken out, and the mean ratio
    of an unbiased method is 1 within its standard errors (ours from the batches, the
    reference's from its own: 5 sigma, of two independent estimates)."""
    long = bake(sphere, BakeSettings(method="reference", spp=512, batches=16, seed=9))
    path = tmp_path / "ref.exr"
    write_exr(path, long.image, exr_metadata(BakeSettings(), long), exr_channels(long))
    ref = Reference.from_exr(path)
    assert ref.variance is not None
    assert np.allclose(ref.variance, long.std.astype(np.float64) ** 2, rtol=1e-6, atol=0)
    rep = compare(sphere, ("reference",), 0.3, BakeSettings(spp=8, batches=8, seed=3), ref)
    region = caustic_region(ref.luminance)
    assert rep["region_from"] == "reference" and rep["region_pixels"] == int(region.sum())
    (row,) = rep["rows"]
    lum = rep["results"]["reference"].image.astype(np.float64).mean(axis=2)
    d2 = ((lum - ref.luminance)[region] ** 2).mean() - ref.variance[region].mean()
    assert row["rmse"] == pytest.approx(math.sqrt(max(d2, 0.0)) / ref.luminance[region].mean(), rel=1e-9)
    ref_se = long.region_mean(region)[1] / ref.luminance[region].mean()
    assert abs(row["ratio"] - 1) < 5 * math.hypot(row["ratio_se"], ref_se), row


def test_a_reference_of_another_size_or_none_to_compare_is_refused(sphere):
    ref = Reference(np.ones((10, 10)), None, "small.exr")
    with pytest.raises(SceneError, match=r"reference 'small.exr' is 10 x 10 pixels, the scene's caustic layer 48 x 36"):
        compare(sphere, ("reference",), 0.1, BakeSettings(spp=2, batches=2, seed=1), ref)
    with pytest.raises(SceneError, match="listed twice"):
        compare(sphere, ("sms", "sms"), 0.1, BakeSettings(spp=2, batches=2, seed=1))


def test_a_scene_without_caustics_says_so_once():
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder("Empty")
    b.plane("Floor", (0, 0, 0), 4, b.material("floor", "diffuse"), receiver=True)
    b.light("Lamp", "POINT", location=(0, 0, 2), power=100.0)
    b.set_camera((0, -3, 2), (0, 0, 0), lens=35, resolution_x=16, resolution_y=12)
    rep = compare(b.build(), ("reference", "sms"), 0.1, BakeSettings(spp=2, batches=2, seed=1))
    assert rep["rows"] == [] and list(rep["results"]) == ["reference"]
    assert table_lines(rep) == [f"nothing to bake: {rep['nothing_to_bake']}"]
