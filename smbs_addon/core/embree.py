"""embree called per ray from the compiled kernels: the library embreex ships (issue 11).

embreex's ``run`` loops ``rtcIntersect1`` over a batch of rays handed over from Python. A
manifold walk decides each ray from the hit before it (a Newton step needs the chain the last
step traced), so through ``run`` every Newton iteration and chain vertex was a round trip
through Python: a kernel call, an intersect call with its float32 copies and fresh output
arrays, another kernel call; a third of a bake's time went to that traffic, and both cores
could only be kept busy by cutting the walks in blocks. Here the kernels call embree
themselves, one ray at a time, inside one call per block of lanes that holds no GIL.

The library is embreex's own (its wheel bundles libembree4, loaded when embreex is imported),
so embreex stays the one ray tracer. The scene is built with embree's C API the way embreex
builds it (one device, a scene with the robust flag, one triangle geometry with unshared float32
vertices), and the hits are embreex's, bit for bit (tests/test_tracer.py). rtcIntersect1 and
rtcOccluded1 are registered with LLVM under names of our own (``smbs_rtc*``): the kernels refer
to them by name, so they stay cacheable on disk, and no other embree in the process (Blender's
Cycles has one) can answer in their place.
"""
from __future__ import annotations

import ctypes
import glob
import os
import threading
import weakref
from collections import namedtuple

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from ..core.jit import JIT as _JIT

# embree4/rtcore_*.h
# Robust traversal stays on, as Cycles and embreex build: without it the bake's own rays run 13-33% faster
# (bench/embree_flags.py), but rays aimed at a closed mesh's shared edges pass through it (6% of them from
# inside a UV sphere; tests/test_tracer.py), and the walks aim at points on the casters
_SCENE_FLAG_ROBUST = 1 << 2
BUILD_LOW, BUILD_MEDIUM, BUILD_HIGH = 0, 1, 2  # RTCBuildQuality; medium is embree's default
_GEOMETRY_TYPE_TRIANGLE = 0
_BUFFER_TYPE_INDEX, _BUFFER_TYPE_VERTEX = 0, 1
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003
_INVALID_ID = 0xFFFFFFFF
# RTCRayHit as 32-bit words: RTCRay (org, tnear, dir, time, tfar, mask, id, flags), then RTCHit
# (Ng, u, v, primID, geomID, instID[1], and instPrimID[1] where instance arrays are built in),
# 16-byte aligned: 24 words at most
_TFAR, _MASK, _ID, _FLAGS, _PRIM, _GEOM, _INST = 8, 9, 10, 11, 17, 18, 19
_RAYHIT_WORDS = 24
_TMAX = 3e37  # the longest segment (embreex's "no limit" is 1e37 for closest hits)

# what the ray log keeps per ray (bench/throughput.py replays it through embreex):
# origin, direction, segment length, kind (0 closest hit, 1 occlusion)
LOG_COLUMNS = 8


def _find_library() -> str:
    """The embree library of the installed embreex wheel: embreex.libs/ beside the package
    (Linux: libembree4-<hash>.so.4; Windows: embree4.dll) or embreex/.dylibs/ (macOS)."""
    import embreex
    import embreex.rtcore_scene  # noqa: F401  (loads the library and what it needs, e.g. TBB)

    pkg = os.path.dirname(os.path.abspath(embreex.__file__))
    found = []
    for folder in (os.path.join(pkg, os.pardir, "embreex.libs"), os.path.join(pkg, ".dylibs"), pkg):
        for pattern in ("libembree4*.so*", "libembree4*.dylib", "embree4*.dll"):
            found += sorted(glob.glob(os.path.join(folder, pattern)))
    if not found:
        raise ImportError(f"embreex at {pkg} carries no embree 4 library (libembree4 / embree4.dll): "
                          "reinstall embreex 4.4 from its wheel")
    return os.path.normpath(found[0])


def _load():
    lib = ctypes.CDLL(_find_library())
    vp, i, u, sz = ctypes.c_void_p, ctypes.c_int, ctypes.c_uint, ctypes.c_size_t
    for name, res, args in (
            ("rtcNewDevice", vp, [ctypes.c_char_p]), ("rtcReleaseDevice", None, [vp]),
            ("rtcGetDeviceError", i, [vp]), ("rtcNewScene", vp, [vp]), ("rtcSetSceneFlags", None, [vp, i]),
            ("rtcSetSceneBuildQuality", None, [vp, i]),
            ("rtcCommitScene", None, [vp]), ("rtcReleaseScene", None, [vp]), ("rtcNewGeometry", vp, [vp, i]),
            ("rtcSetNewGeometryBuffer", vp, [vp, i, u, i, sz, sz]), ("rtcCommitGeometry", None, [vp]),
            ("rtcAttachGeometry", u, [vp, vp]), ("rtcReleaseGeometry", None, [vp])):
        f = getattr(lib, name)
        f.restype, f.argtypes = res, args
    import llvmlite.binding as llvm

    for name in ("rtcIntersect1", "rtcOccluded1"):
        llvm.add_symbol("smbs_" + name, ctypes.cast(getattr(lib, name), ctypes.c_void_p).value)
    return lib


_LIB = _load()
_DEVICE = None
_DEVICE_LOCK = threading.Lock()


def _device():
    """One embree device for the process (embree devices are thread-safe), made on first use."""
    global _DEVICE
    with _DEVICE_LOCK:
        if _DEVICE is None:
            dev = _LIB.rtcNewDevice(None)
            if not dev:
                raise RuntimeError(f"embree could not start (rtcNewDevice failed: error {_LIB.rtcGetDeviceError(None)})")
            _DEVICE = dev
    return _DEVICE


class Scene:
    """An embree scene of triangles (N, 3, 3), each with its own three vertices (as embreex's
    TriangleMesh makes them from such an array), committed; ``ptr`` is the handle the kernels
    take. Released when the object is. flags and quality: what the bake uses (robust, medium);
    others only for bench/embree_flags.py's comparison."""

    def __init__(self, tri_vertices: np.ndarray, flags: int = _SCENE_FLAG_ROBUST, quality: int = BUILD_MEDIUM):
        v = np.ascontiguousarray(tri_vertices, dtype=np.float32).reshape(-1, 3)
        nt = len(v) // 3
        dev = _device()
        scene = _LIB.rtcNewScene(dev)
        _LIB.rtcSetSceneFlags(scene, flags)
        _LIB.rtcSetSceneBuildQuality(scene, quality)
        self._finalizer = weakref.finalize(self, _LIB.rtcReleaseScene, scene)
        geom = _LIB.rtcNewGeometry(dev, _GEOMETRY_TYPE_TRIANGLE)
        vb = _LIB.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_VERTEX, 0, _FORMAT_FLOAT3, 16, 3 * nt)
        ib = _LIB.rtcSetNewGeometryBuffer(geom, _BUFFER_TYPE_INDEX, 0, _FORMAT_UINT3, 12, nt)
        if not vb or not ib:
            _LIB.rtcReleaseGeometry(geom)
            raise MemoryError(f"embree could not allocate the buffers of {nt:,} triangles "
                              f"(error {_LIB.rtcGetDeviceError(dev)})")
        _as_array(vb, ctypes.c_float, (3 * nt, 4))[:, :3] = v
        _as_array(ib, ctypes.c_uint, (nt, 3))[:] = np.arange(3 * nt, dtype=np.uint32).reshape(nt, 3)
        _LIB.rtcCommitGeometry(geom)
        _LIB.rtcAttachGeometry(scene, geom)
        _LIB.rtcReleaseGeometry(geom)
        _LIB.rtcCommitScene(scene)
        err = _LIB.rtcGetDeviceError(dev)
        if err:
            raise RuntimeError(f"embree could not build the scene of {nt:,} triangles (error {err})")
        self.ptr = int(scene)


def _as_array(address, ctype, shape):
    return np.ctypeslib.as_array(ctypes.cast(address, ctypes.POINTER(ctype)), shape=shape)


# What a kernel that casts rays takes (rays()): the scene handle (0 for a scene without triangles),
# the ray log (n, LOG_COLUMNS): every stride-th ray the call casts while there is room, for
# bench/throughput.py (none by default), and that stride
RayContext = namedtuple("RayContext", "scene log stride")

# What a kernel casts rays with (ray_state): the scene handle, an RTCRayHit (as float32 and uint32
# views) and its address, the ray log and its stride, and the counters (counts[KINDS + kind]: rays
# cast of each kind)
RayState = namedtuple("RayState", "scene rh ri ptr log stride counts")


def rays(scene: "Scene | None", log: np.ndarray | None = None, stride: int = 1) -> RayContext:
    """What a kernel that casts rays takes (RayContext)."""
    if log is None:
        log = np.zeros((0, LOG_COLUMNS), np.float32)
    return RayContext(0 if scene is None else scene.ptr, log, max(1, int(stride)))


# ------------------------------------------------------------------ calls from the kernels
def _call(name):
    @intrinsic
    def call(typingctx, scene, rayhit):
        def codegen(context, builder, sig, args):
            vp = cgutils.voidptr_t
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(ir.VoidType(), [vp, vp, vp]),
                                                "smbs_" + name)
            builder.call(fn, [builder.inttoptr(args[0], vp), builder.inttoptr(args[1], vp),
                              cgutils.get_null_value(vp)])
            return context.get_dummy_value()

        return types.void(scene, rayhit), codegen

    return call


_rtc_intersect1 = _call("rtcIntersect1")
_rtc_occluded1 = _call("rtcOccluded1")


# counters of a kernel call's ray_state: rays logged, rays seen by the log's stride, then rays
# cast per kind (the kernels' own kinds: seed, walk, ...; up to 6)
LOGGED, SEEN, KINDS = 0, 1, 2
COUNTERS = KINDS + 6


def counters() -> np.ndarray:
    """Zero counters, to add kernel calls' counters to."""
    return np.zeros(COUNTERS, np.int64)


@njit(inline="always", **_JIT)
def ray_state(rt):
    """What a kernel casts rays with (RayState), made once per kernel call from rt (RayContext):
    the RTCRayHit 16-byte aligned, its counters zero."""
    buf = np.zeros(_RAYHIT_WORDS + 4, np.float32)
    off = ((16 - buf.ctypes.data % 16) % 16) // 4
    rh = buf[off:off + _RAYHIT_WORDS]
    return RayState(rt.scene, rh, rh.view(np.uint32), rh.ctypes.data, rt.log, rt.stride,
                    np.zeros(COUNTERS, np.int64))


@njit(inline="always", **_JIT)
def _setup(ray, o, d, tmax, kind, occl):
    """The RTCRayHit of a ray as embreex's run sets it up (float64 rounded to float32 as numpy
    rounds it; "no limit" is embreex's 1e37), counted and logged."""
    rh, ri, log, counts = ray.rh, ray.ri, ray.log, ray.counts
    rh[0], rh[1], rh[2], rh[3] = o[0], o[1], o[2], 0.0
    rh[4], rh[5], rh[6], rh[7] = d[0], d[1], d[2], 0.0
    rh[_TFAR] = 1e37 if tmax == np.inf else (_TMAX if tmax > _TMAX else tmax)  # np.minimum: NaN stays
    ri[_MASK], ri[_ID], ri[_FLAGS] = _INVALID_ID, 0, 0
    ri[_PRIM] = ri[_GEOM] = ri[_INST] = _INVALID_ID
    counts[KINDS + kind] += 1
    if log.shape[0]:
        seen = counts[SEEN]
        counts[SEEN] = seen + 1
        n = counts[LOGGED]
        if seen % ray.stride == 0 and n < log.shape[0]:
            for c in range(7):
                log[n, c] = rh[c if c < 3 else (c + 1 if c < 6 else _TFAR)]
            log[n, 7] = 1.0 if occl else 0.0
            counts[LOGGED] = n + 1


@njit(inline="always", **_JIT)
def intersect1(ray, o, d, tmax, kind):
    """The closest hit of the ray o + t d, 0 < t < tmax (3-tuples of float64, rounded to
    float32 as embreex's callers round them): (primitive id, -1 on a miss; embree's float32
    distance). kind: which counter counts it."""
    _setup(ray, o, d, tmax, kind, False)
    if ray.scene == 0:  # a scene without triangles
        return -1, np.inf
    _rtc_intersect1(ray.scene, ray.ptr)
    if ray.ri[_PRIM] == _INVALID_ID:
        return -1, np.inf
    return np.int64(ray.ri[_PRIM]), np.float64(ray.rh[_TFAR])


@njit(inline="always", **_JIT)
def occluded1(ray, o, d, tmax, kind):
    """Whether anything lies on o + t d, 0 < t < tmax."""
    _setup(ray, o, d, tmax, kind, True)
    if ray.scene == 0:
        return False
    _rtc_occluded1(ray.scene, ray.ptr)
    return ray.rh[_TFAR] < 0  # embree 4 marks an occluded ray by tfar = -inf


@njit(**_JIT)
def cast_rays(rt, o, d, tmax, occl, prim, t):
    """Closest hits (occl False: prim, t) or occlusion (occl True: prim 0 where occluded, -1
    where not) of rays o + t d (N, 3), tmax (N,) (empty: no limit); returns the counters
    (ray_state)."""
    ray = ray_state(rt)
    for i in range(o.shape[0]):
        oi = (o[i, 0], o[i, 1], o[i, 2])
        di = (d[i, 0], d[i, 1], d[i, 2])
        tm = tmax[i] if tmax.shape[0] else np.inf
        if occl:
            prim[i] = 0 if occluded1(ray, oi, di, tm, 0) else -1
        else:
            prim[i], t[i] = intersect1(ray, oi, di, tm, 0)
    return ray.counts
