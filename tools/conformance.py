"""The conformance suite's references: Cycles renders of the scenes of testkit/conformance_scenes.py.

    python tools/conformance.py reference NAME [NAME ...] --spp 8192 [--fresh]   # add a round
    python tools/conformance.py status                                 # what is stored

A reference is Cycles' caustic component, caustics on minus off, rendered with the
bpy module (CPU, 2 threads) in two independent halves A and B (different seeds),
stored in ``tests/data/conformance/NAME.npz`` (float32 halves, the mean "off" render,
their sample counts) with a JSON note beside it. Each half is an "on" render less an
"off" render of the same seed and samples, so that light the camera sees through glass
or in a mirror cancels exactly (see add_round). Each ``reference`` call renders one more
round of ``--spp`` samples per half (seeds 2k+1 and 2k+2 in round k) and merges it
into the stored halves, so a noisy reference can be refined later (``--fresh`` starts
over).

Where path tracing cannot find the light (a sun of angle 0 behind water), the "on"
render is Cycles' MNEE (the scene's caustic flags as saved) and "off" clears them.

Reading a reference and judging a bake against it is the test-kit's (testkit/conformance.py).
"""
from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from testkit.conformance import (DATA, diffcol_path, load_reference, reference_path, scene_arrays,
                                 summary)
from testkit.cycles import read_exr_rgb, render, set_render


def render_diffuse_color(name: str, blend: Path, spp: int = 64, threads: int = 2) -> np.ndarray:
    """Cycles' Diffuse Color pass of scene NAME ((H,W,3), top row first): where a receiver's colour
    is a texture, the albedo our per-albedo layer is multiplied by, as the add-on's compositor does
    (BakeResult.per_albedo). Stored beside the reference (diffcol_path)."""
    import bpy

    from smbs_addon.io.exr import read_passes

    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    set_render(scene, spp, 1, False, threads)
    scene.view_layers[0].use_pass_diffuse_color = True
    scene.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "diffcol.exr"
        scene.render.filepath = str(path)
        bpy.ops.render.render(write_still=True)
        chans = read_passes(path)
        if "Diffuse Color.R" not in chans:
            raise RuntimeError(f"{name}: the render has no Diffuse Color pass")
        dc = np.stack([chans[f"Diffuse Color.{ch}"] for ch in "RGB"], axis=-1).astype(np.float64)
    np.savez_compressed(diffcol_path(name), diffcol=dc.astype(np.float32), spp=np.asarray(spp))
    return dc


def add_round(name: str, spp: int, threads: int = 2, fresh: bool = False) -> dict:
    """Render one more round of the reference of scene NAME and merge it in (fresh: start over).

    Each half's "on" render is paired with an "off" render of the same seed and samples, and the
    half is their difference: Cycles draws the same random numbers for a camera path until its
    first diffuse vertex, so light the camera sees through glass or in a mirror (a light's image
    in a glass cube, a sun's glint on water) is the same sample for sample in both and cancels
    exactly. With one "off" render shared by both halves (as references were made before) that
    light's noise stayed in the reference, the same in both halves, so their spread did not show
    it: on a bevelled glass cube, where the camera sees the area light through the cube, a shared
    1024-spp "off" put 10-15% too much caustic in the pixels seen through the cube."""
    from testkit import conformance_scenes as scenes  # bpy: loaded when needed

    mnee = name in scenes.MNEE_REFERENCE
    DATA.mkdir(parents=True, exist_ok=True)
    old = None if fresh or not reference_path(name).exists() else load_reference(name)
    k = 0 if old is None else int(old["rounds"])
    with tempfile.TemporaryDirectory() as tmp:
        blend = scenes.build(name, Path(tmp))
        if np.any(scene_arrays(name).mat_textured) and (fresh or not diffcol_path(name).exists()):
            render_diffuse_color(name, blend, threads=threads)
        secs = {}
        halves, offs = {}, []
        for tag, seed in (("a", 2 * k + 1), ("b", 2 * k + 2)):
            p_on, p_off = Path(tmp) / f"on_{tag}.exr", Path(tmp) / f"off_{tag}.exr"
            secs["on_" + tag] = render(blend, spp, seed, True, threads, p_on, keep_mnee=mnee)
            secs["off_" + tag] = render(blend, spp, seed, False, threads, p_off)
            on, off_half = read_exr_rgb(p_on), read_exr_rgb(p_off)
            halves[tag] = on - off_half
            offs.append(off_half)
    off_new = 0.5 * (offs[0] + offs[1])
    if old is None:
        a, b, off, n = halves["a"], halves["b"], off_new, spp
        meta = {"scene": name, "method": "Cycles MNEE (shadow caustics)" if mnee else "Cycles path tracing",
                "paired_off": True, "seconds": 0.0, "rounds_spp": []}
    else:
        n0 = int(old["spp_half"])
        n = n0 + spp
        a = (old["a"] * n0 + halves["a"] * spp) / n
        b = (old["b"] * n0 + halves["b"] * spp) / n
        off = (old["off"] * n0 + off_new * spp) / n
        meta = old["meta"]
    meta["seconds"] = round(meta["seconds"] + sum(secs.values()), 1)
    meta["rounds_spp"].append(spp)
    import bpy

    meta.update(blender=bpy.app.version_string, threads=threads, device="CPU",
                how="a, b: two independent halves of Cycles' caustics on - off, each 'off' render with the "
                    "seed and samples of its 'on' render (seeds 2k+1, 2k+2 in round k); clamps, Filter "
                    "Glossy, denoising and adaptive sampling off")
    np.savez_compressed(reference_path(name), a=a.astype(np.float32), b=b.astype(np.float32),
                        off=off.astype(np.float32), spp_half=np.asarray(n), rounds=np.asarray(k + 1),
                        meta=np.asarray(json.dumps(meta)))
    s = summary(name)
    meta["summary"] = s
    (DATA / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n")
    return s


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reference", help="render one more round of references")
    r.add_argument("names", nargs="+")
    r.add_argument("--spp", type=int, required=True, help="samples per half in this round")
    r.add_argument("--fresh", action="store_true", help="start the reference over (its stored rounds are dropped)")
    r.add_argument("--threads", type=int, default=2)
    sub.add_parser("status", help="print what is stored")
    args = ap.parse_args(argv)
    from testkit import conformance_scenes as scenes  # bpy: loaded once the arguments are read
    if args.cmd == "reference":
        names = list(scenes.SCENES) if args.names == ["all"] else args.names
        for name in names:
            if name not in scenes.SCENES:
                ap.error(f"unknown scene '{name}'")
            s = add_round(name, args.spp, args.threads, args.fresh)
            print(f"{name}: {s['spp']} spp, relative standard error {s['relative_se']:.2%}, "
                  f"halves {s['halves_ratio']:.3f}", flush=True)
    else:
        for name in scenes.SCENES:
            if reference_path(name).exists():
                try:
                    s = summary(name)
                except ValueError:
                    print(f"{name:24s} (shared 'off' render: render it again with --fresh)")
                    continue
                meta = load_reference(name)["meta"]
                print(f"{name:24s} {s['spp']:7d} spp  se {s['relative_se']:6.2%}  halves "
                      f"{s['halves_ratio']:.3f}  {meta['seconds']:7.0f} s  {meta['method']}")
            else:
                print(f"{name:24s} (no reference)")


if __name__ == "__main__":
    main()
