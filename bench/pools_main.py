"""bench/pools.py's "main" row: the default bake of main's tree (MAIN, the code before issue 61) on a pool
exported by this tree, its batch images at their CPU seconds in bench/results/pools/NAME_main.npz.

    python bench/pools_main.py pool_hdri 24 16 [MAIN]     (scene, spp, batches; run from any folder)
"""
import glob
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
MAIN = sys.argv[4] if len(sys.argv) > 4 else "/work/main"
sys.path.insert(0, MAIN)
from smbs_addon import BakeSettings, bake  # noqa: E402  (main's, from MAIN)
from smbs_addon.scene.arrays import Scene  # noqa: E402

assert __import__("smbs_addon").__file__.startswith(MAIN)
name, spp, batches = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
sc = Scene.load(sorted(glob.glob(str(ROOT / ".cache" / "conformance" / f"{name}-*.npz")))[-1])
c0 = time.process_time(); bake(sc, BakeSettings(spp=1, batches=1, threads=2)); fixed = time.process_time() - c0
c0, t0 = time.process_time(), time.perf_counter()
r = bake(sc, BakeSettings(spp=spp, batches=batches, threads=2))
cpu, wall = time.process_time() - c0, time.perf_counter() - t0
np.savez_compressed(ROOT / "bench" / "results" / "pools" / f"{name}_main.npz",
                    batches=np.asarray(r.batch_luminance, np.float32), cpu=cpu, wall=wall, fixed=fixed, meta=json.dumps({"variant": "main (auto, before issue 61)", "spp": spp}))
print(name, "main", cpu, wall, fixed, r.stats["relative_error"], flush=True)
