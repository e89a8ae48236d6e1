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

And a kernel loaded from the cache runs the code a fresh compile runs (_install_callees_first).
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


# A kernel's library holds a copy of every helper it calls without inlining (numba links the helper's
# library into the caller's, its functions weak, and optimizes the whole again: the copy's machine code
# is not the helper's own). In a fresh compile the helper compiles first, as a library of its own, and
# LLVM's loader binds the kernel's calls to that definition (a weak symbol already defined is not
# defined again); a kernel loaded from the disk cache alone binds them to its own copies. The two
# differ: walk_lanes' copy of the walk's loop (walk_jobs) walked 1.4x slower than walk_jobs' own
# (bench/results/cache_load.md). So before a cached kernel of the package loads, the cached entries of
# the helpers it holds copies of load first (and theirs before them), as a fresh compile has them.
_LOADING: set = set()  # the helpers being loaded (a recursion guard)


def _held_functions(libdata, own: str) -> list:
    """The package's functions whose code a cached library holds besides its own function (numba's
    serialized library: name, "object", (object code, the module it links into callers as bitcode))."""
    import llvmlite.binding as ll

    _, kind, data = libdata
    if kind != "object":
        return []
    prefix = "_ZN" + "".join(f"{len(p)}{p}" for p in _PACKAGE.split("."))
    return [fn.name for fn in ll.parse_bitcode(data[1]).functions
            if not fn.is_declaration and fn.name.startswith(prefix) and fn.name != own]


def _dispatcher_of(symbol: str):
    """The dispatcher of a function of the package by its mangled name (numba's: _ZN, each part of the
    module and the function's name as <length><part>, then its tags and types), or None."""
    parts, rest = [], symbol[3:]
    while rest[:1].isdigit():
        n = len(rest) - len(rest.lstrip("0123456789"))
        size = int(rest[:n])
        parts.append(rest[n:n + size])
        rest = rest[n + size:]
    module = sys.modules.get(".".join(parts[:-1]))
    found = getattr(module, parts[-1], None) if parts else None
    found = getattr(found, "dispatcher", found)  # kernels.TypedOnce
    return found if hasattr(found, "_cache") and hasattr(found, "compile") else None


def _load_cached(dispatcher, symbol: str) -> None:
    """The overload of dispatcher compiled as symbol (its name ends with its argument types, mangled),
    loaded if its disk cache holds it for this code and this processor (never compiled)."""
    from numba.core import itanium_mangler

    cache = getattr(dispatcher, "_cache", None)
    codegen = dispatcher.targetctx.codegen()
    try:
        index = cache._cache_file._load_index()
        keys = [key for key in index if key == cache._index_key(key[0], codegen)
                and symbol.endswith("E" + itanium_mangler.mangle_args(key[0]))]
    except Exception:  # noqa: BLE001 - no disk cache (cache=False) or numba's internals moved: nothing to load
        return
    for key in keys:
        dispatcher.compile(key[0])


def _install_callees_first():
    """numba's rebuilding of a cached function, for the package's functions: the helpers whose copies its
    library holds (_held_functions) load first from their own cache entries (_load_cached), each of them
    the same way. A helper that fails to load leaves the kernel its own copy (slower, the same results)."""
    try:
        from numba.core import caching
    except ImportError:  # pragma: no cover - numba's layout changed: default loading
        return
    rebuild = caching.CompileResultCacheImpl.rebuild

    def rebuild_callees_first(self, target_context, payload):
        if getattr(self.locator, "_smbs_per_module", False):
            try:
                held = _held_functions(payload[0], payload[1].mangled_name)
            except Exception:  # noqa: BLE001 - numba's payload changed: the kernel binds its own copies
                held = []
            for symbol in held:
                dispatcher = _dispatcher_of(symbol)
                if dispatcher is not None and id(dispatcher) not in _LOADING:
                    _LOADING.add(id(dispatcher))
                    try:
                        _load_cached(dispatcher, symbol)
                    except Exception:  # noqa: BLE001 - e.g. an unreadable entry: the kernel binds its own copy
                        pass
                    finally:
                        _LOADING.discard(id(dispatcher))
        return rebuild(self, target_context, payload)

    caching.CompileResultCacheImpl.rebuild = rebuild_callees_first


_install_locator()
_install_callees_first()
