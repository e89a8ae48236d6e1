"""Where SMBS's trigger 2 (back-lit) should look on chains of two or more vertices.

    .venv/bin/python bench/backlit_vertex.py [--spp 2] [--seed 1] [--scenes a,b,...]

The paper states trigger 2 for x2, the first specular vertex: the light sample on the wrong
side of its surface for the interaction. On a chain of one vertex that is exact. On longer
chains the light's side of x2 says nothing certain: light reflected off a pane's back face
(T R T) enters and leaves by the front face, with x0 and the light on the same side of it.
This bakes the conformance scenes whose chains have two or more vertices with SMS and with
SMBS under each reading of walk.WalkConfig.backlit_vertex ("first": x2 of every chain;
"last": the vertex the light meets, against the vertex before it; "single": chains of one
vertex only), the same seed and spp, and writes per chain type the success rate (walks that
converged / walks started), mutations per solution and large mutations, plus the bake's own
relative_error. The walks' success does not depend on timing, so any machine will do.
Writes backlit_vertex.md.
"""
from __future__ import annotations

import argparse
import dataclasses
import importlib
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

from testkit import conformance as conf
from smbs_addon import BakeSettings, bake

bake_module = importlib.import_module("smbs_addon.baking.settings")
SCENES = ("through_glass_disk", "cube_white_rect", "cube_grey", "lens_area", "sphere_refraction_spot",
          "sphere_point_soft")
VARIANTS = (("sms", None), ("smbs", "first"), ("smbs", "last"), ("smbs", "single"))


def run(name, method, where, spp, seed):
    """One bake; where (None for SMS) replaces the walks' backlit_vertex."""
    original = bake_module.BakeSettings.manifold_options

    def options(self, method=None):
        o = original(self, method)
        return o if where is None else dataclasses.replace(o, walk=dataclasses.replace(o.walk, backlit_vertex=where))

    bake_module.BakeSettings.manifold_options = options
    try:
        t = time.perf_counter()
        r = bake(conf.scene_arrays(name), BakeSettings(method=method, spp=spp, batches=spp, seed=seed))
    finally:
        bake_module.BakeSettings.manifold_options = original
    (light,) = r.stats["lights"].values()
    return {"wall": time.perf_counter() - t, "chains": light.get("by_chain", {}), "est": r.stats["relative_error"],
            "large": light.get("large_mutations", {})}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--spp", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    args = ap.parse_args(argv)
    lines = ["# Trigger 2 (back-lit): which vertex it reads", "",
             f"Made by `python bench/backlit_vertex.py --spp {args.spp} --seed {args.seed} --scenes {args.scenes}` "
             "(see the script's docstring). Per chain type of two or more vertices: success rate / mutations per "
             "solution / large mutations (all three triggers). Chains of one vertex (R, T) are left out: every "
             "reading tests them alike. `est.` is the bake's own relative_error (all chains).", "",
             "| scene | chain | SMS | SMBS, first | SMBS, last | SMBS, single |", "|---|---|---|---|---|---|"]
    summary = ["", "| scene | SMS est. | first est. | last est. | single est. |", "|---|---|---|---|---|"]
    for name in args.scenes.split(","):
        res = {}
        for method, where in VARIANTS:
            res[(method, where)] = r = run(name, method, where, args.spp, args.seed)
            print(f"{name} {method} {where or ''}: {r['wall']:.1f} s, est {r['est']:.3f}, large {r['large']}",
                  flush=True)
        chains = sorted({c for r in res.values() for c in r["chains"] if len(c) > 1}, key=lambda c: (len(c), c))
        for c in chains:
            cells = []
            for v in VARIANTS:
                ch = res[v]["chains"].get(c)
                cells.append("-" if ch is None else f"{ch['success_rate']:.3f} / {ch['mutations_per_success']:.0f} / "
                                                    f"{ch['large_mutations']}")
            lines.append(f"| {name} | {' '.join(c)} | " + " | ".join(cells) + " |")
        summary.append(f"| {name} | " + " | ".join(f"{res[v]['est']:.3f}" for v in VARIANTS) + " |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "backlit_vertex.md").write_text("\n".join(lines + summary) + "\n")
    print(f"wrote {args.out / 'backlit_vertex.md'}")


if __name__ == "__main__":
    main()
