"""Compile the kernels before the first bake: ``python -m smbs_addon prepare [--jobs N]``.

A kernel compiles with numba on its first use after installing or updating (jit.py) and loads
from the disk cache afterwards; a first bake that compiles the kernels it needs costs a few
minutes more on a 2-core machine (compiles.py measures it). prepare makes a handful of tiny
bakes that between them use the kernels bakes use (every light type, a mirror and an absorbing
glass with Cycles' Bump Map Correction, a plain and a textured, coated floor, every method and
both estimators), so a farm node, a CI machine or an artist's first bake finds them compiled.
With jobs > 1 the bakes are shared out over that many processes (numba compiles one kernel at a
time in a process; its cache writes each kernel's file whole, so processes compiling at once do
not corrupt one another).

The disk cache is kept per name the package is imported under (jit.py), so the processes import
the core under the name this module was imported by, from the same folder: ``smbs_addon`` for
``python -m smbs_addon prepare``, the extension's name for the operator ``smbs.prepare_kernels``
in Blender (the panel's Prepare Kernels, or ``blender -b --python-expr "import bpy;
bpy.ops.smbs.prepare_kernels()"`` on a farm node), whose processes are Blender's own Python.
"""
from __future__ import annotations

import importlib
import json
import math
import os
import subprocess
import sys
import threading
import time

import numpy as np

from ..core.compiles import CompileWatch, counted
from ..core.errors import BakeCancelled
from .settings import BakeSettings
from ..scene.builder import SceneBuilder
from .bake import bake

# (scene, settings) of the bakes, in the order one process makes them; part i of n takes every
# n-th from i. Two parts split the compiling between the walks (the first bake: walks alone, no
# photon pre-pass, pilots or hand-off) and the photons, eye paths and gathering (the light
# tracer's bakes); each part's later bakes find most of the other's kernels in the cache.
WALKS_ONLY = dict(method="smbs", guide=False, pilots=0, handoff=0.0, indirect=False)
BAKES = (
    ("plain", WALKS_ONLY),
    ("plain", dict(method="reference")),
    ("plain", dict(method="smbs")),
    ("textured", dict(method="reference")),
    ("plain", dict(method="sms", estimator="biased")),
    ("textured", dict(method="auto")),
    ("plain", dict(method="mnee")),
    ("textured", dict(method="smbs")),
    ("plain", dict(method="sms")),
)


_BAKE_LINE = "bake "  # run()'s line per bake

# the kernels a bake calls from Python (each compiles the helpers it calls inside it): ready()
# looks for them in the disk cache
KERNELS = ("walk.walk_lanes", "trials.bernoulli_lanes", "newton.chain_solve", "handoff.handoff_lanes",
           "handoff.segments_near", "photons.photon_lanes", "eye.eye_lanes", "gather.gather_lanes", "eye.camera_splats",
           "film.splat")  # module.kernel under smbs_addon.kernels
_KERNELS_PACKAGE = __name__.rsplit(".", 2)[0] + ".kernels"  # under whatever name the package is imported


def ready() -> bool | None:
    """Whether numba's disk cache holds the KERNELS compiled for this code and this processor,
    under the name this module is imported by (jit.py), so that a bake loads them instead of
    compiling: True or False; None where this numba keeps its cache otherwise than numba 0.60
    (no telling). Reads their cache index files (~15 ms); compiles nothing. A kernel for a rarer
    setting (the textured coat, say) may still compile in a bake where this says True."""
    try:
        for name in KERNELS:
            module, _, attr = name.partition(".")
            kernel = getattr(importlib.import_module(f"{_KERNELS_PACKAGE}.{module}"), attr)
            kernel = getattr(kernel, "dispatcher", kernel)  # typed.TypedOnce
            this_cpu = kernel.targetctx.codegen().magic_tuple()
            # the index is empty where its stamp is not this code's (jit.py); its keys are
            # (signature, the processor compiled for, ...)
            if not any(key[1] == this_cpu for key in kernel._cache._cache_file._load_index()):
                return False
    except Exception:  # noqa: BLE001 - numba's cache internals moved: no telling, and no harm
        return None
    return True


def scene(name: str):
    """A small scene that uses what bakes use: a floor seen by the camera, a mirror and an absorbing
    glass ball (smooth shaded, with Cycles' Bump Map Correction) over it, a point, a spot, an area
    and a sun light; 'textured': the floor's colour a texture's, under a Principled glossy coat, and a world
    of an image."""
    b = SceneBuilder(f"prepare_{name}")
    # textured: also a Principled floor's glossy coat over its diffuse (scene.mat_layer)
    layer = (1.5, 0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0) if name == "textured" else (0.0,) * 8
    floor = b.material("floor", "diffuse", color=(0.8, 0.7, 0.6), textured=name == "textured", layer=layer)
    glass = b.material("glass", "dielectric", ior=1.45, bump_correction=True, absorb=(0.2, 0.1, 0.0))
    mirror = b.material("mirror", "conductor", color=(0.9, 0.8, 0.5))
    b.plane("Floor", (0, 0, 0), 4.0, floor, receiver=True)
    b.uv_sphere("Ball", (0, 0, 0.6), 0.4, glass, segments=16, rings=8, caster=True, receiver=True)
    b.plane("Mirror", (-1.2, 0, 0.6), (0.8, 1.2), mirror, normal=(1, 0, 0.3), caster=True)
    b.light("Point", "POINT", location=(0.3, 0.2, 2.5), power=300.0, radius=0.05)
    b.light("Spot", "SPOT", location=(1.5, 0.5, 2.0), target=(0, 0, 0.5), power=300.0, radius=0.05)
    b.light("Area", "AREA", location=(-0.5, 1.0, 2.5), target=(0, 0, 0), power=200.0, size=0.3)
    b.light("Sun", "SUN", location=(0, 0, 5), target=(0.3, 0.2, 0), power=2.0, angle=math.radians(2))
    if name == "textured":  # a world of an image (an HDRI's): its photons leave along the map's directions
        sky = np.full((8, 16, 3), 0.02, np.float32)
        sky[1, 3] = 40.0  # a small sun in it
        b.world((1.0, 1.0, 1.0), image=sky)
    b.set_camera(location=(0.0, -3.0, 2.5), target=(0, 0, 0.3), resolution_x=24, resolution_y=18)
    return b.build()


def bakes(part: int = 0, parts: int = 1):
    """The bakes of part `part` of `parts`: [(scene name, settings keywords)]."""
    return list(BAKES[part::parts])


def run(part: int = 0, parts: int = 1, say=None, progress=None, cancel=None) -> dict:
    """Make part `part`'s bakes in this process; returns {"seconds", "compile_s", "kernels"}.
    progress(fraction, message) before each bake; cancel() returning True stops between and
    inside bakes (BakeCancelled, as bake)."""
    todo = bakes(part, parts)
    scenes = {}
    t0 = time.perf_counter()
    with CompileWatch() as watch:
        for i, (name, kw) in enumerate(todo):
            if cancel is not None and cancel():
                raise BakeCancelled("kernel preparation cancelled")
            if progress is not None:
                progress(i / len(todo), f"compiling the kernels: bake {i + 1} of {len(todo)} ({kw['method']})")
            if name not in scenes:
                scenes[name] = scene(name)
            before = watch.kernels
            bake(scenes[name], BakeSettings(**{**dict(spp=1, batches=2, seed=1, pilots=256), **kw}), cancel=cancel)
            if say is not None:
                say(f"{_BAKE_LINE}{name} {kw}: {counted(watch.kernels - before, 'kernel')} compiled")
    return {"seconds": time.perf_counter() - t0, "compile_s": watch.seconds, "kernels": watch.kernels}


# A process of prepare(): imports the core under the name its parent imported it by (numba's
# disk cache is kept per name, jit.py) from the same folder, without running the packages above
# it (Blender's extension package imports bpy), and makes its part of the bakes.
_IMPORT = """
import importlib, json, os, sys, types
package, folder, path, part, parts = sys.argv[1:6]
names = package.split(".")
if len(names) == 1:
    sys.path.insert(0, os.path.dirname(folder))
for k in range(1, len(names)):
    up = folder
    for _ in range(len(names) - k):
        up = os.path.dirname(up)
    stub = types.ModuleType(".".join(names[:k]))  # the package whose folder is `up`
    stub.__path__ = [up]
    sys.modules[stub.__name__] = stub
sys.path.extend(p for p in json.loads(path) if p not in sys.path)
prepare = importlib.import_module(package + ".prepare")
"""
_PART = _IMPORT + """
out = prepare.run(int(part), int(parts), say=lambda m: print(m, flush=True))
print(f"kernels compiled: {out['kernels']} in {out['compile_s']:.1f} s as {prepare.__name__}", flush=True)
"""

def part_command(code: str, part: int, parts: int) -> list:
    """The command line of prepare()'s process `part` of `parts` running `code` (_PART, or _IMPORT
    and a check of one's own): this Python, the core's package name and folder, sys.path."""
    package = __name__.rpartition(".")[0]
    folder = os.path.dirname(os.path.abspath(__file__))
    return [sys.executable, "-c", code, package, folder, json.dumps(sys.path), str(part), str(parts)]


def prepare(jobs: int | None = None, say=None, progress=None, cancel=None) -> dict:
    """All the bakes, in `jobs` processes (default: one per core, at most one per bake) of this
    Python (sys.executable: Blender's own in Blender), each importing the core under this name;
    one job runs them here. progress(fraction, message) as bakes end; cancel() returning True
    stops the processes (BakeCancelled). Returns {"seconds": wall time, "kernels": compiled,
    "jobs": processes, "as": the name the kernels were compiled under}."""
    jobs = max(1, min(jobs or os.cpu_count() or 1, len(BAKES)))
    t0 = time.perf_counter()
    if jobs == 1:
        out = run(0, 1, say, progress, cancel)
        return {"seconds": out["seconds"], "kernels": out["kernels"], "jobs": 1, "as": __name__}
    procs = [subprocess.Popen(part_command(_PART, i, jobs), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
             for i in range(jobs)]
    lines = [[] for _ in procs]
    readers = [threading.Thread(target=lambda p=p, out=out: out.extend(p.stdout), daemon=True)
               for p, out in zip(procs, lines)]
    for r in readers:
        r.start()
    try:
        while any(p.poll() is None for p in procs):
            if cancel is not None and cancel():
                raise BakeCancelled("kernel preparation cancelled")
            if progress is not None:
                done = sum(x.startswith(_BAKE_LINE) for out in lines for x in list(out))
                progress(done / len(BAKES), f"compiling the kernels in {jobs} processes: {done} of {len(BAKES)} "
                                            f"bakes done")
            time.sleep(0.1)
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
            p.wait()
        for r in readers:
            r.join()
    kernels, names, failed = 0, set(), []
    for i, (p, out) in enumerate(zip(procs, lines)):
        for line in (x.rstrip("\n") for x in out):
            if line.startswith("kernels compiled: "):
                kernels += int(line.split(": ")[1].split()[0])
                names.add(line.rsplit(" as ", 1)[1])
            elif say is not None:
                say(f"[{i + 1}/{jobs}] {line}")
        if p.returncode != 0:
            failed.append(f"part {i + 1} of {jobs} exited with {p.returncode}: {''.join(out).strip()[-2000:]}")
    if failed:
        raise RuntimeError("; ".join(failed))
    return {"seconds": time.perf_counter() - t0, "kernels": kernels, "jobs": jobs, "as": ", ".join(sorted(names))}
