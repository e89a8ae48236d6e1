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
  a stale kernel;
- a read-only install (a farm node, a shared network install, no writable HOME): numba's own
  locators each want a writable folder (NUMBA_CACHE_DIR, the package's __pycache__, the user's
  cache) and without one numba refuses at import ("cannot cache function ...: no locator
  available"). Then the kernels go to a folder of the temporary folder (tempfile.gettempdir()),
  seeded with the entries of every cache folder that can be read (the package's own, numba's user
  cache, NUMBA_CACHE_DIR), so that kernels compiled there load instead of compiling again; one
  line on stderr says so.
"""
from __future__ import annotations

import glob
import hashlib
import os
import shutil
import sys
import tempfile

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


TEMP_CACHE = f"smbs-numba-cache-{os.getuid() if hasattr(os, 'getuid') else 'user'}"  # under gettempdir()
_SAID = []  # the temporary cache's line is said once per process


def _fallback_paths(py_file: str) -> list:
    """The folders a kernel of py_file may be cached in, writable or not, in numba's order of
    preference: NUMBA_CACHE_DIR's, the package's own (__pycache__ beside the file), numba's user
    cache."""
    from numba.core import caching, config

    sub = caching._CacheLocator.get_suitable_cache_subpath(py_file)
    out = [os.path.join(config.CACHE_DIR, sub)] if config.CACHE_DIR else []
    out.append(os.path.join(os.path.dirname(py_file), "__pycache__"))
    try:
        out.append(os.path.join(caching.AppDirs(appname="numba", appauthor=False).user_cache_dir, sub))
    except Exception:  # noqa: BLE001 - no home folder at all: no user cache
        pass
    return out


def _say_temporary(folder: str) -> None:
    if not _SAID:
        _SAID.append(folder)
        print(f"smbs_addon: kernels: no writable cache folder (the package's, numba's user cache, "
              f"NUMBA_CACHE_DIR); compiled kernels are kept in {folder}", file=sys.stderr, flush=True)


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
            inner = _TemporaryLocator.from_function(py_func, py_file)
            if inner is None:
                return None
            self = cls(inner, module)
            inner.seed(self.get_disambiguator())
            return self

    class _TemporaryLocator(caching._CacheLocator):
        """The cache of a read-only install: a folder of the temporary folder, per source folder as
        numba's user cache, seeded with this kernel's entries from the folders that can be read."""

        def __init__(self, py_func, py_file):
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno
            self._qualname = getattr(py_func, "__qualname__", py_func.__name__)
            sub = caching._CacheLocator.get_suitable_cache_subpath(py_file)
            self._cache_path = os.path.join(tempfile.gettempdir(), TEMP_CACHE, sub)

        def get_cache_path(self):
            return self._cache_path

        def get_source_stamp(self):  # pragma: no cover - Locator's stamp is used
            return _stamp()

        def get_disambiguator(self):
            return str(self._lineno)

        def seed(self, disambiguator: str) -> None:
            """Copy the kernel's index and data files (numba's names: [prefix-]module.qualname-
            disambiguator.pyXY[.N].nb?) from the first readable cache folder that has them, unless
            this folder has them already."""
            mod = os.path.splitext(os.path.basename(self._py_file))[0]
            name = f"{mod}.{self._qualname}".replace("<", "").replace(">", "")
            base = glob.escape(f"{name}-{disambiguator}.py{sys.version_info[0]}{sys.version_info[1]}")
            pattern = f"*{base}*.nb[ic]"
            if glob.glob(os.path.join(glob.escape(self._cache_path), pattern)):
                return
            for folder in _fallback_paths(self._py_file):
                found = glob.glob(os.path.join(glob.escape(folder), pattern))
                if any(f.endswith(".nbi") for f in found):
                    for f in found:
                        try:
                            shutil.copy2(f, self._cache_path)
                        except OSError:
                            pass
                    return

        @classmethod
        def from_function(cls, py_func, py_file):
            if not os.path.exists(py_file):
                return None
            self = cls(py_func, py_file)
            try:
                self.ensure_cache_path()
            except OSError:
                return None
            _say_temporary(os.path.dirname(self._cache_path))
            return self

    Locator._smbs_per_module = True
    _TemporaryLocator._smbs_per_module = True
    caching.CacheImpl._locator_classes.insert(0, Locator)


_install_locator()
