"""Render a Cycles reference for the caustic layer of a sample scene.

    python tools/cycles_reference.py sample_blends/mirror.blend --spp 4096 \\
        --out tests/data/cycles_mirror [--threads 2]

Renders the scene with Cycles (bpy module, CPU), in two halves with different seeds,
each with half of ``--spp`` samples:
  * with caustics on (``caustics_reflective = caustics_refractive = True``):
    ``<out>_on_a.exr``, ``<out>_on_b.exr``;
  * with caustics off, with the seed and samples of the half's "on" render:
    ``<out>_off_a.exr``, ``<out>_off_b.exr``.
A half's caustic component is ``on - off`` of its own pair: Cycles draws the same
random numbers for a camera path up to its first diffuse vertex, so what the camera
sees through glass or in a mirror without a diffuse bounce (a light's image in a
glass ball) is the same sample for sample in both and cancels exactly. The caustic
is the mean of the halves, and half the RMS of their difference is its own noise. The images are the Combined pass,
scene linear, 32-bit float OpenEXR (zip), RGB, with an opaque film; the view
transform is set to Standard with no look (EXR output is scene linear either
way; this only keeps any preview consistent). A JSON file ``<out>.json`` holds
the settings, timings and summary statistics.

By default the objects' Cycles caustic-caster flags are cleared before rendering
(not saved): with a caster, a receiver and a caustics light present, Cycles
enables MNEE and culls the BSDF-sampled caustic paths, so e.g. a mirror's
caustic is simply missing. ``--keep-mnee`` renders the scene as saved.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from testkit.cycles import read_exr_rgb, render


def caustic_stats(on_a, on_b, off_a, off_b, frac=0.05, pct=99.5):
    """Mean caustic over the region above frac x its pct-th percentile, and the noise there."""
    ca, cb = on_a - off_a, on_b - off_b
    caus_rgb = 0.5 * (ca + cb)
    caus = caus_rgb.mean(axis=2)
    thr = frac * float(np.percentile(caus, pct))
    region = caus > thr
    half_rms = 0.5 * float(np.sqrt(np.mean(((ca - cb).mean(axis=2)[region]) ** 2))) \
        if region.any() else 0.0
    return dict(threshold=thr, region_pixels=int(region.sum()),
                mean_caustic=float(caus[region].mean()) if region.any() else 0.0,
                mean_caustic_rgb=[float(x) for x in caus_rgb[region].mean(axis=0)]
                if region.any() else [0.0, 0.0, 0.0],
                # noise of one half-image pixel is rms(a-b)/sqrt(2); of the mean of both, rms/2
                half_rms_difference=half_rms,
                max_caustic=float(caus.max()), p995=float(np.percentile(caus, pct)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("blend", type=Path)
    ap.add_argument("--spp", type=int, default=4096, help="total samples of the 'on' render "
                    "(split over two seeds)")
    ap.add_argument("--out", type=Path, required=True, help="output prefix")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seeds", type=int, nargs=2, default=(1, 2))
    ap.add_argument("--keep-mnee", action="store_true",
                    help="keep the scene's caustic caster flags, so Cycles uses MNEE (which also "
                    "culls the path-traced caustics it stands in for); default: plain path tracing")
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)

    import bpy  # noqa: F401  (imported here so --help works without it)

    blend = args.blend.resolve()
    out = args.out.resolve()
    out.parent.mkdir(parents=True, exist_ok=True)
    half = max(1, args.spp // 2)
    jobs = [("on_a", half, args.seeds[0], True), ("off_a", half, args.seeds[0], False),
            ("on_b", half, args.seeds[1], True), ("off_b", half, args.seeds[1], False)]
    timings = {}
    for tag, spp, seed, caustics in jobs:
        path = Path(f"{out}_{tag}.exr")
        dt = render(blend, spp, seed, caustics, args.threads, path, args.keep_mnee)
        timings[tag] = dict(spp=spp, seed=seed, caustics=caustics, seconds=round(dt, 2))
        print(f"{tag}: {spp} spp, seed {seed}, caustics {'on' if caustics else 'off'}: "
              f"{dt:.1f} s -> {path.name}", flush=True)

    stats = caustic_stats(*(read_exr_rgb(f"{out}_{t}.exr") for t in ("on_a", "on_b", "off_a", "off_b")))
    import bpy

    scene = bpy.context.scene
    meta = dict(
        blend=os.path.relpath(blend, Path.cwd()) if blend.is_relative_to(Path.cwd()) else str(blend),
        blender=bpy.app.version_string, resolution=[scene.render.resolution_x,
                                                    scene.render.resolution_y],
        resolution_percentage=scene.render.resolution_percentage,
        renders=timings, threads=args.threads, device="CPU",
        mnee="kept (scene caster flags as saved)" if args.keep_mnee else
             "disabled (is_caustics_caster cleared on all objects): plain path tracing",
        settings=dict(sample_clamp_direct=0.0, sample_clamp_indirect=0.0, blur_glossy=0.0,
                      denoising=False, adaptive_sampling=False,
                      max_bounces=scene.cycles.max_bounces,
                      glossy_bounces=scene.cycles.glossy_bounces,
                      transmission_bounces=scene.cycles.transmission_bounces,
                      diffuse_bounces=scene.cycles.diffuse_bounces,
                      filter=scene.cycles.pixel_filter_type, filter_width=scene.cycles.filter_width,
                      film_transparent=False, view_transform="Standard", exr="32-bit float ZIP RGB"),
        caustic=stats,
        how="caustic = ((on_a - off_a) + (on_b - off_b))/2, each off render with its on render's seed "
            "and samples; region = caustic > 5% of its 99.5th percentile; half_rms_difference = 0.5 * "
            "rms of the halves' difference over the region (noise of the mean)",
    )
    Path(f"{out}.json").write_text(json.dumps(meta, indent=2) + "\n")
    print(json.dumps(stats, indent=2))


if __name__ == "__main__":
    main()
