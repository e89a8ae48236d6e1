"""The conformance suite's library: the exported arrays of a scene of testkit/conformance_scenes.py, its
Cycles reference, and the one way we judge a bake against it (tools/conformance.py renders the references).

A reference is Cycles' caustic component, caustics on minus off, rendered with the
bpy module (CPU, 2 threads) in two independent halves A and B (different seeds),
stored in ``tests/data/conformance/NAME.npz`` (float32 halves, the mean "off" render,
their sample counts) with a JSON note beside it. Each half is an "on" render less an
"off" render of the same seed and samples, so that light the camera sees through glass
or in a mirror cancels exactly (tools/conformance.py, add_round).

Judging (``judge``): the region is chosen on one half, blurred (5 x 5), where it
exceeds 5% of its 99.5th percentile, and the means are taken on the other half, and
the other way round; the two ratios are averaged. Choosing pixels on the very image
one averages keeps the pixels that happen to be noisy-high: on a glass cube at
2 x 4096 spp that alone moved the ratio by 10%.
"""
from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import numpy as np

from . import ROOT, SAMPLE_BLENDS, TEST_DATA

DATA = TEST_DATA / "conformance"
CACHE = ROOT / ".cache" / "conformance"

# (scene, method) pairs that cannot work, and why: the benches show the reason instead of a number
NOT_APPLICABLE = {
    ("water_flat_sun0", "reference"):
        "a sun of angle 0 seen through water: no light path reaches it (Cycles' own path tracing "
        "cannot either; its reference is MNEE)",
}


# the sample scenes users open first (sample_blends/*.blend) that have a Cycles reference of their
# caustic layer (tests/data/cycles_<name>_{on_a,on_b,off}.exr, tools/cycles_reference.py, 2 x 8192
# spp): usable wherever a conformance scene is, under the name sample_<name>
SAMPLES = {"sample_mirror": "mirror", "sample_glass_sphere": "glass_sphere", "sample_glass_spot": "glass_spot"}


def blend_of(name: str, folder: Path) -> Path:
    """The .blend of scene NAME: a sample scene's own file, or a conformance scene built into folder."""
    if name in SAMPLES:
        return SAMPLE_BLENDS / f"{SAMPLES[name]}.blend"
    from . import conformance_scenes as scenes

    return scenes.build(name, Path(folder))


def scene_arrays(name: str):
    """The exported scene (smbs_addon.Scene) of conformance scene NAME: built with the bpy
    module and exported the way the add-on exports, cached by the builder's source (a sample
    scene: its .blend file)."""
    import hashlib

    from smbs_addon.scene.arrays import Scene

    here = Path(__file__).resolve().parent
    src = (here / "conformance_scenes.py").read_bytes() + (here / "blend.py").read_bytes() + \
        (here / "pools.py").read_bytes()
    # the export: every module of the blender package (export.py and the modules it calls; the few that
    # do not, such as composite.py, only cost a fresh export when they change) and of the scene package
    # it builds the arrays with
    for module in sorted((ROOT / "smbs_addon" / "blender").glob("*.py")) + \
            sorted((ROOT / "smbs_addon" / "scene").glob("*.py")):
        src += module.read_bytes()
    if name in SAMPLES:
        src += (SAMPLE_BLENDS / f"{SAMPLES[name]}.blend").read_bytes()
    key = hashlib.sha1(src).hexdigest()[:12]
    path = CACHE / f"{name}-{key}.npz"
    if path.exists():
        return Scene.load(path)
    from smbs_addon.cli.inputs import load_input

    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scene = load_input(str(blend_of(name, Path(tmp))), warn=lambda m: None)
    scene.save(path)
    return scene


def reference_path(name: str) -> Path:
    return DATA / f"{name}.npz"


def load_reference(name: str) -> dict:
    if name in SAMPLES:
        return _sample_reference(SAMPLES[name])
    with np.load(reference_path(name), allow_pickle=False) as z:
        ref = {k: z[k] for k in z.files}
    ref["meta"] = json.loads(str(ref["meta"]))
    if diffcol_path(name).exists():
        with np.load(diffcol_path(name)) as z:
            ref["diffcol"] = z["diffcol"].astype(np.float64)
    if not ref["meta"].get("paired_off"):
        raise ValueError(f"{name}: this reference subtracts one shared 'off' render from both halves, which "
                         "leaves the noise of light seen through glass in it; render it again: python "
                         f"tools/conformance.py reference {name} --spp N --fresh")
    return ref


def _sample_reference(sample: str) -> dict:
    """A sample scene's Cycles reference in the conformance form: halves A and B, each its "on"
    render less its paired "off" one."""
    from .cycles import read_exr_rgb

    base = TEST_DATA / f"cycles_{sample}"
    on_a, on_b, off_a, off_b = (read_exr_rgb(f"{base}_{t}.exr") for t in ("on_a", "on_b", "off_a", "off_b"))
    meta = json.loads(Path(f"{base}.json").read_text())
    return {"a": on_a - off_a, "b": on_b - off_b, "off": 0.5 * (off_a + off_b),
            "spp_half": meta["renders"]["on_a"]["spp"], "meta": meta}


def region_of(lum: np.ndarray, frac: float = 0.05) -> np.ndarray:
    """The caustic region, as a bake picks its own (luminance over 5x5 pixels, 5% of its top)."""
    from smbs_addon.baking.convergence import caustic_region

    return caustic_region(lum, frac)


def _truth(ref: dict, region: np.ndarray | None):
    """The reference's luminance (the mean of its halves), the region (default: its caustic
    region) and the mean over it of its per-pixel variance, (A - B)^2 / 4 in expectation."""
    A, B = ref["a"].mean(axis=2), ref["b"].mean(axis=2)
    truth = 0.5 * (A + B)
    if region is None:
        region = region_of(truth)
    return truth, region, float(((A - B) ** 2 / 4.0)[region].mean())


def noise_floor(ref: dict, region: np.ndarray | None = None) -> float:
    """The reference's own relative RMS noise per pixel (its mean of halves) over region:
    relative_rmse cannot resolve errors much below it."""
    truth, region, ref_var = _truth(ref, region)
    return math.sqrt(ref_var) / float(truth[region].mean())


def relative_rmse(lum: np.ndarray, ref: dict, region: np.ndarray | None = None) -> float:
    """Our image's (H,W luminance) relative RMS error per pixel against the reference over
    region (default: the reference's caustic region), with the reference's own per-pixel
    noise taken out."""
    truth, region, ref_var = _truth(ref, region)
    mse = float(((lum - truth)[region] ** 2).mean() - ref_var)
    return math.sqrt(max(mse, 0.0)) / float(truth[region].mean())


def pattern(lum: np.ndarray, ref: dict, block: int = 6) -> dict:
    """How our image's (H,W luminance) pattern follows the reference's, where a mean over the
    caustic region cannot tell (a caustic network under bumped water holds the flat water's light,
    redistributed): over block x block pixel means, our relative RMS error (the reference's own
    block noise taken out), the correlation, and the reference's own contrast (its blocks' relative
    standard deviation: what an image without the pattern would score)."""
    def blocks(x):
        H, W = x.shape
        return x[:H // block * block, :W // block * block].reshape(H // block, block, W // block, block).mean((1, 3))

    A, Bh = blocks(ref["a"].mean(axis=2)), blocks(ref["b"].mean(axis=2))
    truth, ours = 0.5 * (A + Bh), blocks(lum)
    mse = float(((ours - truth) ** 2).mean() - ((A - Bh) ** 2 / 4.0).mean())
    return {"block_rmse": math.sqrt(max(mse, 0.0)) / float(truth.mean()),
            "correlation": float(np.corrcoef(ours.ravel(), truth.ravel())[0, 1]),
            "contrast": float(truth.std() / truth.mean())}


def judge(batch_luminance: np.ndarray, ref: dict, mask: np.ndarray | None = None) -> dict:
    """Our mean over the caustic region relative to Cycles', with standard errors.

    batch_luminance: (B,H,W) our independent batches (BakeResult.batch_luminance); mask (H,W)
    bool: judge only the region's pixels inside it (view_masks: seen directly, or through
    mirrors and glass)."""
    A, Bh = ref["a"].mean(axis=2), ref["b"].mean(axis=2)
    var_half = ((A - Bh) ** 2) / 2.0  # per-pixel variance of one half (Cycles' pixels are independent)
    ours_img = batch_luminance.mean(axis=0)
    nb = len(batch_luminance)
    ratios, se_refs, se_ours, pix = [], [], [], []
    for sel, judge_img in ((A, Bh), (Bh, A)):
        region = region_of(sel)
        if mask is not None:
            region &= mask
        n = int(region.sum())
        if n == 0:
            raise ValueError("no pixel of the caustic region lies in the mask")
        m_ref = float(judge_img[region].mean())
        se_ref = math.sqrt(float(var_half[region].sum())) / n
        means = batch_luminance[:, region].mean(axis=1)
        m_ours = float(means.mean())
        se_o = float(means.std(ddof=1) / math.sqrt(nb)) if nb > 1 else float("inf")
        ratios.append(m_ours / m_ref)
        se_refs.append(se_ref / m_ref)
        se_ours.append(se_o / m_ref)
        pix.append(n)
    ratio = float(np.mean(ratios))
    se_ref = float(np.mean(se_refs)) / math.sqrt(2.0)  # the two halves judge independently
    se_o = float(np.mean(se_ours))
    sigma = math.sqrt(se_ref ** 2 + se_o ** 2)
    return {"ratio": ratio, "se_ours": se_o, "se_ref": se_ref, "sigma": sigma,
            "pixels": int(np.mean(pix)), "whole_image_ratio": float(ours_img.sum() / (0.5 * (A + Bh)).sum()),
            "within": abs(ratio - 1.0) <= 0.03 + 3.0 * sigma}


def view_masks(scene, sub: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """(direct, through) (H,W) bool over the camera's image: pixels all of whose sub x sub
    primary rays meet a diffuse surface first, and those all of whose rays meet a mirror or
    glass first (the camera sees a receiver through them, or nothing). Pixels on an edge
    between the two are in neither."""
    from smbs_addon.scene import arrays as S
    from smbs_addon.trace.camera import CameraModel
    from smbs_addon.trace.tracer import Tracer

    cam = CameraModel(scene.camera)
    tracer = Tracer(scene, threads=2)
    H, W = scene.camera.height, scene.camera.width
    yy, xx = (a.ravel().astype(float) for a in np.mgrid[0:H, 0:W])
    specular = np.zeros(H * W)
    for sy in range(sub):
        for sx in range(sub):
            o, d, tnear = cam.rays(xx + (sx + 0.5) / sub, yy + (sy + 0.5) / sub)
            h = tracer.intersect(o + tnear[:, None] * d, d)
            kind = np.where(h.hit, scene.mat_kind[scene.tri_material[np.maximum(h.prim, 0)]], -1)
            specular += (kind == S.DIELECTRIC) | (kind == S.CONDUCTOR)
    specular = specular.reshape(H, W) / (sub * sub)
    return specular == 0, specular == 1


def diffcol_path(name: str) -> Path:
    return DATA / f"{name}_diffcol.npz"


def composed_luminance(result, diffcol) -> np.ndarray:
    """(B,H,W) our batches' luminance as the compositor shows them: the layer plus per_albedo x the
    render's Diffuse Color pass where the scene has textured receivers (each batch scaled per pixel
    by the composed mean over the bake's own); the batches as they are elsewhere."""
    if getattr(result, "per_albedo", None) is None:
        return result.batch_luminance
    if diffcol is None:
        raise ValueError("a scene with textured receivers needs its reference's Diffuse Color pass")
    composed = (result.layer() + result.per_albedo * diffcol).mean(axis=2)
    own = result.image.mean(axis=2)
    scale = np.divide(composed, own, out=np.ones_like(composed), where=own > 0)
    return result.batch_luminance * scale[None].astype(np.float32)


def summary(name: str) -> dict:
    ref = load_reference(name)
    A, Bh = ref["a"].mean(axis=2), ref["b"].mean(axis=2)
    region = region_of(0.5 * (A + Bh))
    n = int(region.sum())
    mean = float((0.5 * (A + Bh))[region].mean())
    se = math.sqrt(float((((A - Bh) ** 2) / 4.0)[region].sum())) / n  # of the mean of both halves
    return {"spp": 2 * int(ref["spp_half"]), "region_pixels": n, "mean": mean,
            "relative_se": se / mean if mean > 0 else float("inf"),
            "halves_ratio": float(A[region].mean() / Bh[region].mean())}
