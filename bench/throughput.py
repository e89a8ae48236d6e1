"""How fast the bake casts rays against what embree can: the measurement behind issue 11.

    .venv/bin/python bench/throughput.py [--size 512] [--spp 1] [--scenes sphere,ring,hammered]
        [--methods sms,smbs,reference] [--reps 3] [--out bench/results]

Per scene and method, in one run on the same geometry:
- embree's own rate: incoherent rays (origins uniform in the scene's box, directions uniform on
  the sphere), as many as the bake cast (at most 8 M), closest-hit queries split over all cores
  on threads (one embreex ``run`` call uses one core and releases the GIL);
- the bake's effective rate: the rays it cast / its wall time, and its Newton steps (small and
  large mutations) per second;
- ``ratio``: effective / raw;
- embree's rate on the bake's own rays (``same rays``): every 4th ray the bake cast (offset
  origin, direction, segment length; tracer.RAY_LOG, also from inside the walk kernels), replayed through plain embreex the same
  way, closest-hit or occlusion as cast. Rays from a diffuse floor into a glass ball hit and
  cost about 4x random rays in the scene's box (two thirds of which leave it without a hit);
  ``ratio (same rays)`` is the bake's rate over this one, the share of the time it spends
  tracing; ``ceiling``: same rays / raw, the highest ``ratio`` any bake that casts these rays
  could reach (embree doing nothing else): on the glass sphere and the hammered mirror 0.19-0.32,
  under issue 11's 0.5;
- the bake's wall time: the median of --reps bakes after a warm-up bake (the kernels loaded from
  numba's cache, the scene's memo), none of them recording rays (that takes one more bake);
  --reps 1 times the one bake that records, as this script did before 2026-11-26;
- ``cpu/wall``: the process's CPU time over the bake's wall time
  (2.0 means both cores busy the whole time); peak memory (the process's maximum resident set;
  the recorded rays add about 7 bytes per ray cast).

Scenes (testkit/scenes.py): the glass sphere under an area light, the gold ring lit from the side,
the hammered mirror; at --size x --size pixels (``name:size`` for one scene: the hammered mirror's
unbiased walks need thousands of Bernoulli trials per lane, 285 s for SMS at 128 x 128).
Writes throughput_last.md under --out, a run's table (the next run overwrites it); the results
kept, with what changed between them, are hand-written sections of bench/results/throughput.md,
which this script does not touch.
"""
from __future__ import annotations

import argparse
import resource
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

from testkit import scenes
from smbs_addon import BakeSettings, bake
import smbs_addon.trace.tracer as tracer_mod
from smbs_addon.trace.tracer import default_threads

SCENES = {
    "sphere": lambda res: scenes.glass_sphere_scene(resolution=res),
    "ring": lambda res: scenes.ring_scene(resolution=res),
    "hammered": lambda res: scenes.hammered_mirror_scene(resolution=res),
}


def raw_rate(scene, n: int, seed: int = 0) -> float:
    """Rays per second of plain embreex on this scene's triangles, threaded over all cores."""
    import embreex.mesh_construction as emc
    import embreex.rtcore_scene as ers

    es = ers.EmbreeScene()
    emc.TriangleMesh(es, np.ascontiguousarray(scene.tri_vertices, dtype=np.float32))
    lo, hi = scene.bounds()
    rng = np.random.default_rng(seed)
    o = (lo + (hi - lo) * rng.random((n, 3))).astype(np.float32)
    d = rng.standard_normal((n, 3))
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    threads = default_threads()
    bounds = np.linspace(0, n, threads * 4 + 1).astype(int)
    slices = [slice(bounds[i], bounds[i + 1]) for i in range(len(bounds) - 1)]
    es.run(o[:1000], d[:1000], output=1)  # warm-up
    t = time.perf_counter()
    with ThreadPoolExecutor(max_workers=threads) as ex:
        list(ex.map(lambda sl: es.run(o[sl], d[sl], output=1), slices))
    return n / (time.perf_counter() - t)


class RayRecorder:
    """Keeps every 4th ray of each embree call the bake makes, from Python or from the walk
    kernels (tracer.RAY_LOG: at most tracer.RAY_LOG_ROWS per kernel call), as float32."""

    def __enter__(self):
        tracer_mod.RAY_LOG = self.logs = []
        self._rows, tracer_mod.RAY_LOG_ROWS = tracer_mod.RAY_LOG_ROWS, 1 << 20
        return self

    def __exit__(self, *exc):
        tracer_mod.RAY_LOG = None
        tracer_mod.RAY_LOG_ROWS = self._rows


def replay_rate(scene, logs: list) -> float:
    """Rays per second of plain embreex on the recorded rays, each ray's kind (closest hit or
    occlusion within its segment), all rays of a kind joined and cut in parts of 65536,
    threaded over all cores."""
    import embreex.mesh_construction as emc
    import embreex.rtcore_scene as ers

    es = ers.EmbreeScene()
    emc.TriangleMesh(es, np.ascontiguousarray(scene.tri_vertices, dtype=np.float32))
    rays = np.concatenate(logs) if logs else np.zeros((0, 8), np.float32)
    jobs = []
    for occl in (False, True):
        r = rays[(rays[:, 7] > 0) == occl]
        o, d, t = np.ascontiguousarray(r[:, 0:3]), np.ascontiguousarray(r[:, 3:6]), np.ascontiguousarray(r[:, 6])
        for a in range(0, len(r), 65536):
            sl = slice(a, a + 65536)
            jobs.append((o[sl], d[sl], t[sl], occl))

    def run(job):
        o, d, t, occl = job
        if occl:
            es.run(o, d, query="OCCLUDED", dists=t)
        else:
            es.run(o, d, dists=t, output=1)

    n = sum(len(j[0]) for j in jobs)
    if n == 0:
        return float("nan")
    run(jobs[0])  # warm-up
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=default_threads()) as ex:
        list(ex.map(run, jobs))
    return n / (time.perf_counter() - t0)


def measure(name: str, method: str, size: int, spp: int, reps: int = 1) -> dict:
    """One row: with reps > 1, a warm-up bake (the kernels loaded from the cache, the scene's
    memo) and the median wall time of reps bakes (cpu/wall over them all); the rays replayed
    (same rays) are recorded in one more bake of the same seed, so the recording's own cost is
    in no timed bake. reps = 1: one bake, timed and recorded (the table's older rows)."""
    sc = SCENES[name]((size, size))
    settings = BakeSettings(method=method, spp=spp, batches=min(spp, 2) if spp > 1 else 1, seed=1)
    walls, cpus = [], []
    if reps > 1:
        bake(sc, settings)
    for _ in range(reps):
        cpu0 = time.process_time()
        t = time.perf_counter()
        if reps > 1:
            r = bake(sc, settings)
        else:
            with RayRecorder() as rec:
                r = bake(sc, settings)
        walls.append(time.perf_counter() - t)
        cpus.append(time.process_time() - cpu0)
    if reps > 1:
        with RayRecorder() as rec:
            bake(sc, settings)
    wall, cpu_wall = float(np.median(walls)), sum(cpus) / sum(walls)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    st = r.stats
    rays = int(st["rays"])
    n_raw = int(min(max(rays, 100_000), 8_000_000))
    raw = float(np.median([raw_rate(sc, n_raw, seed) for seed in range(1 if reps == 1 else 3)]))
    same = replay_rate(sc, rec.logs)
    del rec
    # Newton steps of the primary walks and of the unbiased estimator's Bernoulli re-walks
    steps = int(st.get("mutations", 0)) + sum(int(L.get("bernoulli_mutations", 0)) for L in st["lights"].values())
    return {"scene": name, "method": method, "size": size, "spp": spp, "wall": wall, "rays": rays,
            "effective": rays / wall, "raw": raw, "ratio": rays / wall / raw, "same": same,
            "ratio_same": rays / wall / same, "ceiling": same / raw, "steps_per_s": steps / wall,
            "cpu_wall": cpu_wall, "peak_gib": peak, "wall_min": min(walls), "wall_max": max(walls)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--spp", type=int, default=1)
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--methods", default="sms,smbs,reference")
    ap.add_argument("--reps", type=int, default=3,
                    help="timed bakes per row after a warm-up, their median (1: one bake, timed while recorded)")
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    args = ap.parse_args(argv)
    rows = []
    for spec in args.scenes.split(","):
        name, _, size = spec.partition(":")  # name:size overrides --size for that scene
        for method in args.methods.split(","):
            rows.append(measure(name, method, int(size or args.size), args.spp, args.reps))
            r = rows[-1]
            print(f"{name} {method}: {r['wall']:.2f} s ({r['wall_min']:.2f}-{r['wall_max']:.2f}), {r['rays']:,} rays, effective {r['effective'] / 1e6:.2f} M/s, "
                  f"raw {r['raw'] / 1e6:.2f} M/s, ratio: {r['ratio']:.3f}, same rays {r['same'] / 1e6:.2f} M/s, "
                  f"ratio (same rays): {r['ratio_same']:.3f}, ceiling: {r['ceiling']:.2f}, "
                  f"steps {r['steps_per_s'] / 1e3:.0f} k/s, "
                  f"cpu/wall: {r['cpu_wall']:.2f}, peak {r['peak_gib']:.2f} GiB", flush=True)
    lines = ["# Throughput: the bake's ray rate against embree's", "",
             f"Made by `python bench/throughput.py --size {args.size} --spp {args.spp} --scenes {args.scenes} "
             f"--methods {args.methods} --reps {args.reps}` ({default_threads()} threads). Wall: the median of "
             f"{args.reps} bakes after a warm-up (min-max), cpu/wall over them. Raw: plain embreex, incoherent "
             "closest-hit rays threaded over all cores, as many as the bake cast (the median of 3 runs); same "
             "rays: every 4th ray the bake cast, recorded in one more bake, replayed through plain embreex "
             "threaded over all cores; ceiling: same rays / raw, the highest ratio a bake casting these rays "
             "could reach. Peak memory is the process's maximum so far (it only grows down the table).", "",
             "| scene | method | wall s | rays | effective M rays/s | raw M rays/s | ratio | same rays M rays/s "
             "| ratio (same rays) | ceiling | Newton steps k/s | cpu/wall | peak GiB |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} {r['size']}^2 | {r['method']} | {r['wall']:.2f} ({r['wall_min']:.2f}-"
                     f"{r['wall_max']:.2f}) | {r['rays']:,} | {r['effective'] / 1e6:.2f} | "
                     f"{r['raw'] / 1e6:.2f} | {r['ratio']:.3f} | {r['same'] / 1e6:.2f} | {r['ratio_same']:.3f} | "
                     f"{r['ceiling']:.2f} | "
                     f"{r['steps_per_s'] / 1e3:.0f} | {r['cpu_wall']:.2f} | "
                     f"{r['peak_gib']:.2f} |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "throughput_last.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
