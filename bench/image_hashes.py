"""Hash the images of a fixed set of bakes, to show that a change of code left every image bit for bit.

    python bench/image_hashes.py OUT.json [--base BASE.json] [--quick]

Bakes 9 builder scenes (testkit.scenes) with each method (spp 2, seed 3), and 31 conformance scenes
(their arrays exported from Blender, testkit.conformance.scene_arrays) with SMS, SMBS and auto (spp
4, seed 3); hashes each bake's image, variance, std, batch images and textured parts, its statistics'
counts (rays, walks, successes, mutations, photons, splats, hand-off paths, Bernoulli trials) and each
scene's arrays. --base compares with an earlier OUT.json and prints what differs (exit 1 if any).
--quick: the builder scenes alone. Used for every step of the house's redesign (issue 57).
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

from smbs_addon import BakeSettings, bake
from testkit import scenes as T

COUNT_KEYS = ("walks", "successes", "mutations", "photons", "splats", "handoff_paths", "bernoulli_trials")
BUILDER = {
    "glass_sphere": lambda: T.glass_sphere_scene(),
    "ring": lambda: T.ring_scene(),
    "wavy_mirror": lambda: T.wavy_mirror_scene(),
    "water48": lambda: T.water_scene(resolution=48),
    "water_sun48": lambda: T.water_scene(light="sun", resolution=48),
    "pane": lambda: T.pane_scene(),
    "hammered": lambda: T.hammered_mirror_scene(),
    "mirror": lambda: T.mirror_scene(resolution=(64, 48)),
    "world_mirror": lambda: T.world_mirror_scene(),
}
CONFORMANCE = ["lens_area", "gold_cylinder", "pool_sun4", "mesh_light_ball", "sphere_point_soft", "linked_lamps",
               "egg_sun_spot", "cube_grey", "through_glass_disk", "hidden_kinds", "shadow_linked_ball",
               "principled_glow_ball", "shadow_linked_glow", "world_ball", "cube_grey_reflect", "checker_floor",
               "tinted_ball", "film_ball", "rough_glass_ball", "mix_floor", "hdri_ball", "coated_floor",
               "bumped_pool_sun", "water_flat_sun0", "normal_mapped_pool_sun", "ray_visibility", "anodized_ring",
               "fresnel_glass_ball", "mesh_light_mirror", "rough_mirror_ggx", "bumped_floor"]


def digest(*arrays) -> str:
    m = hashlib.sha1()
    for a in arrays:
        if a is None:
            m.update(b"none")
            continue
        a = np.ascontiguousarray(a)
        m.update(str(a.dtype).encode())
        m.update(str(a.shape).encode())
        m.update(a.tobytes())
    return m.hexdigest()[:16]


def counts(stats: dict) -> dict:
    out = {}

    def walk(d, prefix):
        for k, v in d.items():
            if isinstance(v, dict):
                walk(v, prefix + k + ".")
            elif (k.startswith("rays") or k in COUNT_KEYS) and isinstance(v, (int, np.integer)):
                out[prefix + k] = int(v)
    walk(stats, "")
    return out


def bake_hash(scene, **settings) -> dict:
    r = bake(scene, BakeSettings(**settings))
    c = counts(r.stats)
    return {"img": digest(r.image, r.variance, r.std, r.batch_luminance, r.textured, r.per_albedo),
            "counts": digest(np.array(sorted(c.items()), dtype=object).astype(str)), "rays": c.get("rays")}


def scene_hash(scene) -> str:
    parts = []
    for f in dataclasses.fields(scene):
        v = getattr(scene, f.name)
        parts.append(v if isinstance(v, np.ndarray) else np.frombuffer(repr(v).encode(), dtype=np.uint8))
    return digest(*parts)


def hashes(quick: bool) -> dict:
    out, t0 = {}, time.time()
    for name, make in BUILDER.items():
        scene = make()
        out[f"scene:{name}"] = scene_hash(scene)
        for method in ("reference", "sms", "smbs", "mnee", "auto"):
            out[f"{name}:{method}"] = bake_hash(scene, method=method, spp=2, seed=3)
        print(f"{name} {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    if not quick:
        from testkit.conformance import scene_arrays  # bpy: only for the conformance scenes

        for name in CONFORMANCE:
            scene = scene_arrays(name)
            out[f"confscene:{name}"] = scene_hash(scene)
            for method in ("sms", "smbs", "auto"):
                out[f"conf:{name}:{method}"] = bake_hash(scene, method=method, spp=4, seed=3)
            print(f"{name} {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out")
    p.add_argument("--base")
    p.add_argument("--quick", action="store_true")
    args = p.parse_args(argv)
    got = hashes(args.quick)
    Path(args.out).write_text(json.dumps(got, indent=1, sort_keys=True))
    if not args.base:
        return 0
    base = json.loads(Path(args.base).read_text())
    differ = [k for k in got if base.get(k) != got[k]]
    print(f"{len(got)} compared, {len(differ)} differ")
    for k in differ:
        print(f"  {k}: {base.get(k)} -> {got[k]}")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
