"""How the package's kernels compile with numba: the settings they share and their disk cache.

Kernels (kernels.py, embree.py, optics.py, lights.py, thinfilm.py, rough.py) compile on first use and are cached on disk (cache=True; numba
falls back to a user cache folder when the package folder is read-only). nogil: threads run
them side by side. error_model="numpy": x / 0 is inf or NaN as in numpy, never an exception.

The cache locator installed here does two things numba's own does not:
- one disk cache per name the package is imported under. numba's cache is keyed by the
  source file, but a cached kernel rebuilds its environment by importing its module by the
  name it was compiled under: the same file imported as smbs_addon.kernels.chain (command line) and
  as bl_ext.<repo>.smbs_caustics.smbs_addon.kernels.chain (Blender) would each fail to load the
  other's entries (ModuleNotFoundError). The module's name goes into the cache file names;
- a stamp over every file that holds kernels. A kernel of kernels.py inlines embree.py's ray
  calls, and numba's stamp covers only the kernel's own file: an edit of embree.py would load
  a stale kernel.
"""
from __future__ import annotations

import hashlib
import os

JIT = dict(cache=True, nogil=True, error_model="numpy", _nrt=True)
# The loops over lanes (kernels' *_rows and walk_jobs, a lane's seed and ray chain, and the per-event
# helpers they call with arrays: optics.scatter1, kernels._coat_factor, thinfilm.f82_film1) compile
# without numba's reference counting. There numba calls NRT_incref and NRT_decref for every array a
# variable takes, a tuple gives up or an inlined helper receives, per lane and Newton step (a call
# each, most of them on arrays whose count need not change), and its pruning pass leaves them where
# the code branches: those two functions were the hottest addresses of a walk's perf
# profile (10% of its samples); without them the walks take 0.64-0.90 of the time (bench/ab.py).
# Such a kernel may not allocate (numba refuses to compile it) nor receive a new array from a call
# (never freed: tests/test_kernels.py counts numba's blocks over whole bakes): the kernel that calls
# it allocates, holds the arrays and returns them. Everything else sets _nrt=True: numba would
# otherwise give a helper the setting of whichever kernel compiled it first.
LANES = dict(JIT, _nrt=False)
# Helpers are plain njit, called: LLVM inlines a small one into each caller's machine code anyway,
# while numba's own inline="always" types it again at every call site (the walks' first compile took
# 154 s with the small helpers so marked, 71 s without: bench/results/first_bake.md). A helper keeps
# inline="always" where LLVM would leave a call in a hot kernel (bench/inlined_calls.py lists the
# calls left), or where it is the Newton step itself (kernels._lane_blocks, _lane_solve, lane_newton:
# called, a hammered mirror's bakes were 8-15% slower).

_PACKAGE = __name__.rsplit(".", 2)[0]  # smbs_addon, under whatever name it is imported
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _kernel_files() -> list:
    """Every file of the package that holds compiled code (it imports this module's settings), and
    this one: a kernel inlines code from other files, so their edits must reach its stamp too."""
    out = [os.path.abspath(__file__)]
    for folder, _, names in sorted(os.walk(_ROOT)):
        for name in sorted(names):
            path = os.path.join(folder, name)
            if name.endswith(".py") and path != out[0]:
                with open(path, encoding="utf-8") as f:
                    if "jit import" in f.read():
                        out.append(path)
    return out


_FILES = _kernel_files()


def _stamp():
    out = []
    for f in _FILES:
        st = os.stat(f)
        out += [st.st_mtime, st.st_size]
    return tuple(out)


def _install_locator():
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba's layout changed: default caching
        return

    class Locator(caching._CacheLocator):
        def __init__(self, inner, module):
            self._inner = inner
            self._tag = hashlib.sha1(module.encode()).hexdigest()[:10]

        def ensure_cache_path(self):
            self._inner.ensure_cache_path()

        def get_cache_path(self):
            return self._inner.get_cache_path()

        def get_source_stamp(self):
            return _stamp()

        def get_disambiguator(self):
            return f"{self._inner.get_disambiguator()}-{self._tag}"

        @classmethod
        def from_function(cls, py_func, py_file):
            module = getattr(py_func, "__module__", None) or ""
            if not module.startswith(_PACKAGE + "."):
                return None
            for base in caching.CacheImpl._locator_classes:
                if base is not cls and not getattr(base, "_smbs_per_module", False):
                    inner = base.from_function(py_func, py_file)
                    if inner is not None:
                        return cls(inner, module)
            return None

    Locator._smbs_per_module = True
    caching.CacheImpl._locator_classes.insert(0, Locator)


_install_locator()
