"""embree's scene flags and build quality: what they cost the bake's own rays, and what they lose.

    .venv/bin/python bench/embree_flags.py [--scenes sphere:512:sms,ring:512:smbs,hammered:48:sms] [--reps 3]

Per scene (testkit/scenes.py, ``name:size:method``): one bake of one sample per pixel records every 4th
ray it casts (bench/throughput.py's RayRecorder), and the recorded rays are cast again, on one
thread, through embree scenes built from the same triangles with each variant's flags and build
quality (smbs_addon/embree.py builds with RTC_SCENE_FLAG_ROBUST at the default, medium, quality).
Printed: each variant's rays per second (the best of --reps), its build time, and how many rays
meet another triangle than the robust scene's (an edge both triangles share: the same point) or
miss where it hits. Then the edge test: from inside a closed UV sphere (64 x 32), rays aimed at
points on its triangles' edges and at its vertices, which every ray must hit; the robust scene
lets none of the edge rays through (bench/results/throughput.md, 2026-11-29)."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

import throughput  # bench/throughput.py, beside this script
from smbs_addon import BakeSettings, bake
from smbs_addon.core import embree
from smbs_addon.scene.builder import SceneBuilder

ROBUST = embree._SCENE_FLAG_ROBUST
VARIANTS = {"robust, medium (ours)": (ROBUST, embree.BUILD_MEDIUM), "robust, high": (ROBUST, embree.BUILD_HIGH),
            "robust, low": (ROBUST, embree.BUILD_LOW), "fast, medium": (0, embree.BUILD_MEDIUM),
            "fast, high": (0, embree.BUILD_HIGH)}


def build(tri_vertices, flags, quality):
    """(embree.Scene with these flags and build quality, seconds its build took)."""
    t = time.perf_counter()
    sc = embree.Scene(tri_vertices, flags, quality)
    return sc, time.perf_counter() - t


def cast(scene, o, d, tmax, occl):
    """(primitive or -1 per ray (occlusion: 0 where blocked), seconds), one thread."""
    rt = embree.rays(scene)
    prim = np.zeros(len(o), np.int64)
    t0 = time.perf_counter()
    for kind in (False, True):
        sel = np.flatnonzero(occl == kind)
        p, tt = np.zeros(sel.size, np.int64), np.zeros(sel.size)
        embree.cast_rays(rt, o[sel], d[sel], tmax[sel], kind, p, tt)
        prim[sel] = p
    return prim, time.perf_counter() - t0


def recorded_rays(name: str, size: int, method: str):
    sc = throughput.SCENES[name]((size, size))
    with throughput.RayRecorder() as rec:
        bake(sc, BakeSettings(method=method, spp=1, seed=1))
    r = np.concatenate(rec.logs)
    f64 = lambda a: np.ascontiguousarray(a, np.float64)  # noqa: E731
    return sc, f64(r[:, 0:3]), f64(r[:, 3:6]), f64(r[:, 6]), r[:, 7] > 0


def edge_rays(segments=64, rings=32, n_edge=80_000, seed=1):
    """A closed UV sphere's triangles, and from two points inside it rays aimed at points on its
    triangles' edges and at its vertices: {(source, target): (o, d)}."""
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.uv_sphere("Ball", (0.1, 0.2, 0.3), 1.0, m, segments=segments, rings=rings)
    tv = b.build().tri_vertices
    rng = np.random.default_rng(seed)
    tri, e, a = rng.integers(0, len(tv), n_edge), rng.integers(0, 3, n_edge), rng.random(n_edge)[:, None]
    targets = {"edges": tv[tri, e] * (1 - a) + tv[tri, (e + 1) % 3] * a, "vertices": tv.reshape(-1, 3)}
    out = {}
    for src_name, src in (("centre", np.array([0.1, 0.2, 0.3])), ("off centre", np.array([0.4, 0.1, 0.5]))):
        for t_name, q in targets.items():
            d = q - src
            out[(src_name, t_name)] = (np.ascontiguousarray(np.broadcast_to(src, d.shape)),
                                       d / np.linalg.norm(d, axis=1, keepdims=True))
    return tv, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="sphere:512:sms,ring:512:smbs,hammered:48:sms")
    ap.add_argument("--reps", type=int, default=3)
    args = ap.parse_args(argv)
    for spec in args.scenes.split(","):
        name, size, method = spec.split(":")
        sc, o, d, tmax, occl = recorded_rays(name, int(size), method)
        print(f"{name} {size}^2 {method}: {len(sc.tri_vertices):,} triangles, {len(o):,} recorded rays", flush=True)
        ref = None
        for label, (flags, quality) in VARIANTS.items():
            v, build_s = build(sc.tri_vertices, flags, quality)
            best, prim = np.inf, None
            for _ in range(args.reps):
                prim, dt = cast(v, o, d, tmax, occl)
                best = min(best, dt)
            ref = prim if ref is None else ref
            other = prim != ref
            print(f"  {label:22s} {len(o) / best / 1e6:6.2f} M rays/s, build {build_s * 1e3:6.1f} ms, "
                  f"other triangle {int((other & (prim >= 0) & (ref >= 0)).sum())}, "
                  f"missed {int((other & (prim < 0)).sum())}, hit instead {int((other & (ref < 0)).sum())}", flush=True)
    tv, rays = edge_rays()
    print("edge test (closed UV sphere 64 x 32, rays from inside; every one should hit):")
    for label, (flags, quality) in VARIANTS.items():
        v, _ = build(tv, flags, quality)
        lost = []
        for (src, tgt), (o, d) in rays.items():
            prim, _ = cast(v, o, d, np.full(len(o), np.inf), np.zeros(len(o), bool))
            lost.append(f"{src} at {tgt} {int((prim < 0).sum())} of {len(o):,}")
        print(f"  {label:22s} missed: " + ", ".join(lost))


if __name__ == "__main__":
    main()
