"""Which of the package's functions the kernels still call: the calls left in their machine code.

    python bench/inlined_calls.py [--method walks|smbs|sms|mnee|reference|prepare] [--json FILE]

A helper marked ``inline="always"`` is inlined by numba itself, which types it again at every call
site (the first compile's largest cost, bench/compile_times.py); a plain ``njit`` helper compiles
once and LLVM decides, caller by caller, whether to inline it. This copies the package into a
temporary folder (its numba cache empty), makes one 1-spp bake of prepare's plain scene there
(``prepare``: all of prepare's bakes, every kernel a bake uses), and prints, per compiled function
and signature, the package's functions its machine code still calls (numba's large code model
calls through a register: ``movabsq $<symbol>, %reg`` then ``callq *%reg``). A function's machine
code includes the helpers it calls that were not inlined, so a call shows under every caller above
it. A small helper that shows up here under a hot kernel costs a call per use: mark it
``inline="always"``; one that never shows up is inlined by LLVM and needs no mark. Listed too:
numba's reference counts (``NRT_incref``, ``NRT_decref``), none in a kernel compiled with
jit.LANES, a few where a kernel allocates and returns its arrays. ``--json``
writes {function and signature: {callee: references}} to compare two trees.
"""
from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r'''
import importlib, json, re, sys
from numba.core.registry import CPUDispatcher
from smbs_addon import BakeSettings, bake
from smbs_addon.baking import prepare

method, out = sys.argv[1], sys.argv[2]
if method == "prepare":
    prepare.run(0, 1)
else:
    kw = prepare.WALKS_ONLY if method == "walks" else dict(method=method)
    bake(prepare.scene("plain"), BakeSettings(spp=1, seed=1, **kw))


def dotted(symbol):
    """_ZN10smbs_addon7kernels10_hit_pointB... -> smbs_addon.kernels.chain.hit_point (Itanium-style names)."""
    s, parts = symbol[3:], []
    while s[:1].isdigit():
        k = re.match(r"\d+", s).group()
        parts.append(s[len(k):len(k) + int(k)])
        s = s[len(k) + int(k):]
    return ".".join(parts)


found, seen = {}, set()
for mod in ("kernels.chain", "kernels.eye", "kernels.film", "kernels.gather", "kernels.handoff", "kernels.keyed",
            "kernels.large_mutation", "kernels.newton", "kernels.photons", "kernels.trials", "kernels.walk",
            "shading.optics", "shading.fresnel", "shading.coat", "shading.absorption", "shading.microfacet",
            "shading.energy", "shading.lights", "shading.thinfilm", "core.embree", "core.vec3"):
    for name, v in vars(importlib.import_module("smbs_addon." + mod)).items():
        v = getattr(v, "dispatcher", v)  # kernels.TypedOnce
        if not isinstance(v, CPUDispatcher) or id(v) in seen:  # a function imported by another module
            continue
        seen.add(id(v))
        own = f"{v.py_func.__module__}.{v.py_func.__name__}"
        for sig, cres in v.overloads.items():
            calls, asm = {}, cres.library.get_asm_str()
            for m in re.finditer(r"movabsq\s+\$(_ZN\d[0-9A-Za-z_$.]+),", asm):
                callee = dotted(m.group(1))
                if callee.startswith("smbs_addon.") and callee != own:
                    calls[callee] = calls.get(callee, 0) + 1
            wrapper = False  # numba's Python wrapper of a function releases its arguments: not counted
            for line in asm.splitlines():
                if re.match(r"[_A-Za-z][0-9A-Za-z_$.]*:", line):
                    wrapper = line.startswith("_ZN7cpython")
                m = re.search(r"movabsq\s+\$(NRT_incref|NRT_decref),", line)
                if m and not wrapper:
                    calls[m.group(1)] = calls.get(m.group(1), 0) + 1
            found[f"{own} {sig}"] = calls
for key in sorted(found):
    name = key.split(" ", 1)[0]
    calls = ", ".join(f"{c.rpartition('.')[2]} {n}" for c, n in sorted(found[key].items()))
    print(f"{name.removeprefix('smbs_addon.'):32s} {calls or '-'}")
if out:
    with open(out, "w") as f:
        json.dump(found, f, indent=1, sort_keys=True)
'''


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="walks", choices=("walks", "smbs", "sms", "mnee", "reference", "prepare"))
    ap.add_argument("--json", default="", help="write the calls per function and signature here")
    a = ap.parse_args(argv)
    out = os.path.abspath(a.json) if a.json else ""
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(ROOT / "smbs_addon", Path(tmp) / "smbs_addon",
                        ignore=shutil.ignore_patterns("__pycache__"))
        env = dict(os.environ, PYTHONDONTWRITEBYTECODE="1")
        return subprocess.call([sys.executable, "-c", CHILD, a.method, out], cwd=tmp, env=env)


if __name__ == "__main__":
    sys.exit(main())
