"""The compiled kernels (smbs_addon/kernels.py) against the numpy reference they replace:
constraints.blocks + block_solve (the Newton step and the geometric term's dx1/dy) on random
chains of both constraint forms, point and directional light ends, reflections and
refractions; and the degenerate cases (coincident vertices, grazing refraction, singular
Jacobians) give ok False and finite zeros, as the ok flags of the numpy code say."""
import numpy as np
import pytest

from smbs_addon.kernels import chain

from smbs_addon.kernels import large_mutation

from smbs_addon.kernels import newton

from smbs_addon.kernels import records

from smbs_addon.kernels import typed
from smbs_addon.walks.walk import ANGLE_DIFF, HALF_VECTOR
from testkit.oracles.constraints import block_solve, blocks, specular_map
from smbs_addon.shading.light_samples import LightEnd
from smbs_addon.scene.geometry import Vertex, pack
from smbs_addon.core.vec import cross, frame, normalize


def _random_chain(rng, n, types, directional):
    """Vertices strung roughly along +z from x0 to the light, with random normals and
    tangents and normal derivatives: many valid lanes, some grazing or TIR."""
    k = len(types)
    x0 = rng.normal(size=(n, 3)) * 0.3
    verts = []
    for j in range(k):
        p = rng.normal(size=(n, 3)) * 0.4 + np.array([0, 0, 1.0 + j])
        ng = normalize(rng.normal(size=(n, 3)) * 0.4 + np.array([0, 0, 1.0]))
        ns = normalize(ng + rng.normal(size=(n, 3)) * 0.1)
        s = normalize(cross(ng, rng.normal(size=(n, 3))))
        t = cross(ng, s)
        verts.append(Vertex(p=p, ng=ng, n=ns, s=s, t=t, dn_s=rng.normal(size=(n, 3)) * 0.2,
                            dn_t=rng.normal(size=(n, 3)) * 0.2, prim=np.zeros(n, np.int64),
                            obj=np.zeros(n, np.int64), mat=np.zeros(n, np.int64)))
    etas = [rng.uniform(1.1, 1.8, n) for _ in range(k)]
    if directional:
        y = normalize(rng.normal(size=(n, 3)) * 0.3 + np.array([0, 0, 1.0]))
    else:
        y = rng.normal(size=(n, 3)) * 0.4 + np.array([0, 0, 2.0 + k])
    ys, yt = frame(normalize(rng.normal(size=(n, 3))))
    return x0, verts, etas, LightEnd(directional, y, ys, yt)


def _kinds(types):
    return np.array([1 if c == "T" else 0 for c in types], np.int64)


def _close(a, b, ok):
    a, b = a[ok], b[ok]
    scale = np.maximum(np.abs(b).max(axis=tuple(range(1, b.ndim)), keepdims=True), 1e-300)
    return np.abs(a - b) / scale


@pytest.mark.parametrize("form", [ANGLE_DIFF, HALF_VECTOR])
@pytest.mark.parametrize("types", ["R", "T", "RR", "TT", "TRT", "TRRT"])
@pytest.mark.parametrize("directional", [False, True])
def test_chain_solve_matches_numpy(form, types, directional):
    rng = np.random.default_rng(hash((form, types, directional)) % 2**32)
    n = 2000
    x0, verts, etas, light = _random_chain(rng, n, types, directional)
    k = len(types)
    C, A, B, D, okc = blocks(form, types, x0, verts, etas, light)
    with np.errstate(all="ignore"):
        delta, oks = block_solve(A, B, D, C[..., None])
        rhs = np.zeros(A.shape[:2] + (2, 2))
        rhs[:, k - 1] = -D[:, k - 1]
        X, oksg = block_solve(A, B, D, rhs)
    F, _ = pack(verts)
    E = np.stack(etas, 1)
    args = (form == HALF_VECTOR, _kinds(types), x0, F, E, light.y, light.ys, light.yt, directional)
    out0, ok0 = newton.chain_solve(0, *args)
    out1, ok1 = newton.chain_solve(1, *args)
    ref_ok = okc & oks
    assert ref_ok.mean() > 0.3  # the test exercises real chains
    np.testing.assert_array_equal(ok0, ref_ok)
    np.testing.assert_array_equal(ok1, okc & oksg)
    assert _close(out0[:, :, 0], delta[:, 0, :, 0], ok0).max() < 1e-12
    assert _close(out1, X[:, 0], ok1).max() < 1e-12
    assert np.all(out0[~ok0] == 0) and np.all(np.isfinite(out0)) and np.all(np.isfinite(out1))
    # the walk's proposal: the Newton step of x1, shortened and scaled by beta
    idx = rng.permutation(n)[: n // 2]
    beta = rng.uniform(0.1, 1.0, n)
    p, d, okp = newton.newton_proposal(idx, *args, beta, 0.3)
    np.testing.assert_array_equal(okp, ref_ok[idx])
    step = -(delta[idx, 0, 0, 0][:, None] * verts[0].s[idx] + delta[idx, 0, 1, 0][:, None] * verts[0].t[idx])
    ls = np.sqrt(np.sum(step * step, 1))
    with np.errstate(all="ignore"):
        step *= np.minimum(1.0, 0.3 / np.maximum(ls, 1e-300))[:, None]
    p_ref = verts[0].p[idx] + beta[idx, None] * step
    assert np.abs(p - p_ref)[okp].max() < 1e-12
    assert np.abs(d - normalize(p_ref - x0[idx]))[okp].max() < 1e-12


def test_degenerate_chains_are_flagged_not_nan():
    rng = np.random.default_rng(3)
    n = 64
    x0, verts, etas, light = _random_chain(rng, n, "TT", False)
    verts[0].p[:8] = x0[:8]  # x1 on x0: the first segment has no direction
    verts[1].p[8:16] = verts[0].p[8:16]  # two vertices at one point
    light.y[16:24] = verts[1].p[16:24]  # the light on the last vertex
    for f in ("s", "t", "dn_s", "dn_t"):  # a vertex without tangents: singular Jacobian
        getattr(verts[0], f)[24:32] = 0.0
    etas[0][32:40] = 50.0  # grazing / TIR-like refraction
    verts[0].n[40:48] = 0.0  # no normal at all
    F, _ = pack(verts)
    args = (False, _kinds("TT"), x0, F, np.stack(etas, 1), light.y, light.ys, light.yt, False)
    with np.errstate(all="ignore"):
        C, A, B, D, okc = blocks(ANGLE_DIFF, "TT", x0, verts, etas, light)
        _, oks = block_solve(A, B, D, C[..., None])
    for mode in (0, 1):
        out, ok = newton.chain_solve(mode, *args)
        assert np.all(np.isfinite(out))
        assert not ok[:32].any()
        if mode == 0:
            np.testing.assert_array_equal(ok, okc & oks)
    p, d, okp = newton.newton_proposal(np.arange(n), *args, np.ones(n), 1.0)
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(d)) and not okp[:32].any()


def test_specular_map_kernel_matches_numpy():
    rng = np.random.default_rng(5)
    n = 500
    w = normalize(rng.normal(size=(n, 3)))
    nrm = normalize(rng.normal(size=(n, 3)))
    eta = rng.uniform(1.0, 2.0, n)
    for refract, kind in ((False, "R"), (True, "T")):
        ref, ok = specular_map(kind, w, nrm, eta)
        for i in range(n):
            out, oki = newton.smap(refract, tuple(w[i]), tuple(nrm[i]), eta[i])
            assert oki == ok[i]
            assert np.abs(np.array(out) - ref[i]).max() < 1e-15


@pytest.mark.parametrize("types", ["R", "TT", "TRT"])
@pytest.mark.parametrize("directional", [False, True])
def test_large_proposal_matches_numpy(types, directional):
    from smbs_addon.walks.walk import MAX_HALVINGS
    from testkit.oracles.large_mutation import large_direction

    rng = np.random.default_rng(len(types) + 10 * directional)
    n = 1000
    x0, verts, etas, light = _random_chain(rng, n, types, directional)
    verts[0].obj[:] = rng.integers(0, 3, n)
    obj_lo = np.array([[-0.5, -0.5, 0.5], [-2.0, -2.0, 0.0], [0.3, 0.3, 0.9]])
    obj_hi = obj_lo + np.array([[1.0, 1.0, 1.0], [4.0, 4.0, 3.0], [0.2, 0.2, 0.2]])
    scale = np.where(rng.random(n) < 0.3, 0.25, 1.0)
    obj1 = verts[0].obj
    d_ref, ok_ref = large_direction(types, verts, etas, light, x0, obj_lo[obj1], obj_hi[obj1], scale)
    F, I = pack(verts)
    idx = np.arange(n)
    d, ok = large_mutation.large_proposal(idx, _kinds(types), x0, F, I, np.stack(etas, 1), light.y, directional, obj_lo,
                             obj_hi, scale, MAX_HALVINGS)
    np.testing.assert_array_equal(ok, ok_ref)
    assert 0.2 < ok.mean() and np.abs(d - d_ref)[ok].max() < 1e-14


_CACHE_USE = r"""
import importlib, sys, types
import numpy as np
name, path = sys.argv[1], sys.argv[2]
if name != "smbs_addon.kernels.chain":  # the same files under another package name, as Blender imports the extension
    top, sub = name.split(".")[:2]
    for pkg, where in ((top, []), (top + "." + sub, [path])):
        m = types.ModuleType(pkg)
        m.__path__ = where
        sys.modules[pkg] = m
K = importlib.import_module(name)
assert K.__file__.startswith(path)
F = np.zeros((3, 1, K.NF))
F[:, 0, 2] = 1.0
err, front = K.end_mismatch(np.arange(3), F, np.tile([0.0, 0.0, 1.0], (3, 1)), np.tile([0.0, 0.0, 5.0], (3, 1)), False)
assert np.allclose(err, 0.0) and front.all()
print("CACHE-OK")
"""


def test_disk_cache_survives_two_module_names(tmp_path):
    """A kernel cached under one module name (Blender's bl_ext.*.smbs_caustics...) must not break
    a later process importing the same file as smbs_addon.kernels.chain, and the other way round
    (jit.py's cache locator)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    path = str(root / "smbs_addon")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(root)}
    for name in ("smbs_caustics_test.smbs_addon.kernels.chain", "smbs_addon.kernels.chain", "smbs_caustics_test.smbs_addon.kernels.chain",
                 "smbs_addon.kernels.chain"):
        proc = subprocess.run([sys.executable, "-c", _CACHE_USE, name, path], env=env, capture_output=True,
                              text=True, timeout=600, cwd=tmp_path)
        assert proc.returncode == 0 and "CACHE-OK" in proc.stdout, proc.stderr[-2000:]


def test_disk_cache_follows_every_file_with_kernels(tmp_path):
    """A kernel of kernels/chain.py inlines core/embree.py's ray calls, and numba's own stamp covers
    only the kernel's file: jit.py's stamp covers every file with kernels, so after an edit of
    embree.py alone a cached kernel is compiled again instead of loaded stale."""
    import os
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    src = Path(__file__).resolve().parents[2] / "smbs_addon"
    pkg = tmp_path / "copy" / "smbs_addon"
    shutil.copytree(src, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    use = _CACHE_USE + "print('HITS', sum(K.end_mismatch.stats.cache_hits.values()))\n"

    def hits():
        proc = subprocess.run([sys.executable, "-c", use, "copied.smbs_addon.kernels.chain", str(pkg)], env=env,
                              capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert proc.returncode == 0 and "CACHE-OK" in proc.stdout, proc.stderr[-2000:]
        return int(proc.stdout.split("HITS")[1])

    assert hits() == 0 and hits() == 1  # compiled, then loaded
    with open(pkg / "core" / "embree.py", "a") as f:
        f.write("# an edit\n")
    assert hits() == 0 and hits() == 1


_CALLS_HELPERS = r"""
import ctypes, struct
from numba.core import caching
from smbs_addon.shading import thinfilm as T
loaded = []  # the functions rebuilt from the disk cache, in the order their code was loaded
rebuild = caching.CompileResultCacheImpl.rebuild


def recorded(self, target_context, payload):
    out = rebuild(self, target_context, payload)
    loaded.append(payload[1].qualname)
    return out


caching.CompileResultCacheImpl.rebuild = recorded
T.f82_film1(20.0, 1.5, 0.6, (0.9, 0.6, 0.3), (0.8, 0.8, 0.8))
kernel = next(iter(T.f82_film1.overloads.values()))
engine = kernel.library._codegen._engine
entry = engine.get_function_address(kernel.fndesc.mangled_name)
end = engine.get_function_address(kernel.fndesc.llvm_cpython_wrapper_name)  # next in the kernel's code
code = ctypes.string_at(entry, end - entry) if 0 < end - entry < 1 << 20 else b""
helper = [c.fndesc.mangled_name for c in T._f82_film_channel.overloads.values()]
# numba's large code model calls through an absolute address (movabsq $<address>, %reg; callq *%reg)
calls = [struct.pack("<Q", engine.get_function_address(name)) in code for name in helper]
print("RESULT", loaded, len(helper), calls)
"""


def test_a_cached_kernel_calls_its_helpers_own_code(tmp_path):
    """A kernel holds a copy of the helpers it calls without inlining (thinfilm.f82_film1 of
    _f82_film_channel, that of iridescence1), optimized again with the kernel: a fresh compile binds
    the kernel's calls to the helper's own code, compiled first; loaded from the disk cache, the
    helpers' own entries load first (jit._install_callees_first) and the kernel calls them too, not
    its copies (walk_lanes' copy of walk_jobs walked 1.4x slower: bench/results/cache_load.md)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PYTHONPATH": str(root)}
    runs = []
    for _ in range(2):  # compiled, then loaded
        proc = subprocess.run([sys.executable, "-c", _CALLS_HELPERS], env=env, capture_output=True, text=True,
                              timeout=600, cwd=tmp_path)
        assert proc.returncode == 0 and "RESULT" in proc.stdout, proc.stderr[-2000:]
        runs.append(proc.stdout.split("RESULT", 1)[1].strip())
    assert runs[0] == "[] 1 [True]"  # compiled in the process: the helper first, its code called
    assert runs[1] == "['iridescence1', '_f82_film_channel', 'f82_film1'] 1 [True]"


def test_cache_stamp_covers_every_file_with_kernels():
    """Every module of the package that compiles with numba (imports jit.JIT) is in jit.py's stamp:
    a kernel inlines or links helpers of other files (optics.scatter1 the rough lobes of rough.py),
    so a file left out of it would let an edit load stale kernels (rough.py was, until stop 52)."""
    import os
    from pathlib import Path

    from smbs_addon.core import jit

    pkg = Path(jit.__file__).resolve().parents[1]
    with_kernels = {str(f) for f in pkg.rglob("*.py") if "@njit" in f.read_text()}
    assert {"microfacet.py", "walk.py", "embree.py"} <= {os.path.basename(f) for f in with_kernels}
    assert with_kernels <= set(jit._FILES)


def test_typed_once_types_a_long_tuple_once(monkeypatch):
    """kernels.TypedOnce: numba's dispatcher types a tuple of more than 4 items in Python on
    every call; through TypedOnce the compiled code is found once per argument key and then
    called directly (no typing: zero typeof_pyval calls), with the dispatcher's results. A new
    key (other dtypes) compiles and is found in turn; where numba would convert an argument
    rather than match it (an int for a float64 signature), the call keeps the dispatcher."""
    from numba import njit
    from numba.core import dispatcher

    @njit
    def total(t, x):
        s = x
        for a in t:
            s += a.sum()
        return s

    calls = []
    real = dispatcher._DispatcherBase.typeof_pyval
    monkeypatch.setattr(dispatcher._DispatcherBase, "typeof_pyval",
                        lambda self, v: calls.append(1) or real(self, v))
    arrays = tuple(np.full(3, float(i)) for i in range(7))
    assert total(arrays, 1.0) == 64.0
    calls.clear()
    total(arrays, 1.0)
    assert len(calls) > 0  # the plain dispatcher types the 7-tuple on every call
    fast = typed.TypedOnce(total)
    assert fast(arrays, 1.0) == 64.0
    calls.clear()
    assert [fast(arrays, 2.0) for _ in range(3)] == [65.0] * 3
    assert calls == []
    ints = tuple(np.full(3, i) for i in range(7))  # int64 arrays: another key, another overload
    assert fast(ints, 1.0) == 64.0 and fast(ints, 1.0) == 64.0
    assert len(fast._entries) == 2

    @njit("float64(float64)")
    def half(x):
        return x / 2

    h = typed.TypedOnce(half)
    assert h(3) == 1.5 and h(3) == 1.5  # int -> float64: converted by the dispatcher, each time
    assert h._entries[typed._arg_key((3,))] is half
    assert h(3.0) == 1.5 and h._entries[typed._arg_key((3.0,))] is not half


def _nrt_outstanding():
    """numba's runtime memory blocks allocated and not yet freed (its counters on from the first call)."""
    import gc

    from numba.core.runtime import _nrt_python, rtsys

    if not _nrt_python.memsys_stats_enabled():
        _nrt_python.memsys_enable_stats()
    gc.collect()
    st = rtsys.get_allocation_stats()
    return st.mi_alloc - st.mi_free, st.alloc - st.free


def test_lane_kernels_count_no_references_refuse_to_allocate_and_the_counters_see_a_leak():
    """jit.LANES: a kernel so compiled writes through its argument arrays and leaves their owners'
    references as they were; one that allocates is refused at compile time; and one that receives
    a new array from a call never frees it, which numba's runtime counters show (the failure
    test_bakes_leave_no_runtime_memory_behind looks for)."""
    import sys

    from numba import njit
    from numba.core.errors import TypingError

    from smbs_addon.core.jit import JIT, LANES

    @njit(**dict(LANES, cache=False))
    def through(t, scale):
        a, b, n = t
        for i in range(a.shape[0]):
            b[i] = a[i] * scale + n
        return b.sum()

    a = np.arange(5.0)
    b = np.zeros(5)
    before = sys.getrefcount(a), sys.getrefcount(b)
    for _ in range(3):
        assert through((a, b, 1), 2.0) == pytest.approx(25.0)
    assert np.array_equal(b, 2.0 * np.arange(5.0) + 1)
    assert (sys.getrefcount(a), sys.getrefcount(b)) == before

    @njit(**dict(LANES, cache=False))
    def allocates(k):
        return np.zeros(k)[0]

    with pytest.raises(TypingError):
        allocates(3)

    @njit(**dict(JIT, cache=False))
    def make(k):
        return np.zeros(k)

    @njit(**dict(LANES, cache=False))
    def receives(out, k):
        out[0] = make(k).sum() + 1.0

    out = np.zeros(1)
    receives(out, 3)  # compiled
    m0, _ = _nrt_outstanding()
    for _ in range(4):
        receives(out, 3)
    assert out[0] == 1.0
    assert _nrt_outstanding()[0] - m0 == 4


@pytest.mark.parametrize("method", ["sms", "smbs", "mnee", "reference"])
def test_bakes_leave_no_runtime_memory_behind(method):
    """Every kernel a bake of the glass sphere runs (seeds, walks, Bernoulli trials, the hand-off,
    photons, gathering, the eye pass) frees what numba's runtime allocated: the loops over lanes
    compiled without reference counting (jit.LANES) neither leak nor free an array twice. The
    second of two equal bakes leaves the runtime's outstanding blocks exactly as it found them."""
    from testkit.scenes import glass_sphere_scene

    from smbs_addon import BakeSettings, bake

    scene = glass_sphere_scene(resolution=(32, 24))
    settings = BakeSettings(method=method, spp=2, seed=5)
    bake(scene, settings)  # compiles, fills whatever a first bake caches
    before = _nrt_outstanding()
    result = bake(scene, settings)
    assert np.isfinite(np.asarray(result.image)).all()
    del result
    assert _nrt_outstanding() == before


def test_packed_floats_is_the_chain_itself_or_packs_a_copy():
    """geometry.packed_floats: a Chain's vertex views give back its F (the geometric term reads
    it where it packed a copy per call: 20% of the manifold pass's numpy on a glass sphere); any
    other list of vertices (reordered, a prefix, copied) gives pack's copy, equal to it."""
    import dataclasses

    from smbs_addon.scene.geometry import packed_floats
    from smbs_addon.walks.walk import Chain

    F = np.random.default_rng(0).random((50, 2, 21))
    ch = Chain(F, np.zeros((50, 2, 3), np.int64), np.zeros(50), np.zeros((50, 3))).take(np.array([3, 1, 4, 1, 5]))
    v = ch.verts
    assert packed_floats(v) is ch.F
    for other in ([v[1], v[0]], v[:1], [dataclasses.replace(x, p=x.p.copy()) for x in v]):
        got = packed_floats(other)
        assert got is not ch.F and np.array_equal(got, pack(other)[0])
    assert np.array_equal(packed_floats([v[1], v[0]])[:, 0], ch.F[:, 1])
