"""Lanes split over threads: one persistent pool per thread count, parts in lane order.

embree's ``run`` and the numba kernels (nogil) release the GIL, so a batch of lanes cut into
contiguous parts runs on several cores. Each part's result is the same whichever thread runs it,
and parts are joined in order: the image does not depend on the thread count.

Whole streams of work run in blocks (``blocks``): walk.newton_walk and trials.bernoulli_trials
cut their lanes into blocks of a fixed size, each one kernel call that walks its lanes and casts
their rays without the GIL, and threads take the blocks in turn. The cut does not depend on the
thread count. Inside a block, ``run`` does not split again: the block's calls run on its own
thread.

Before each block and part, the stop flag (core/signals.py: a signal asked the bake to stop) is
polled; a block that raises (that flag's BakeCancelled, or an error) stops the other threads at
their next block, and the call returns only once they have: no thread goes on with a bake that
has ended.
"""
from __future__ import annotations

import atexit
import itertools
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from . import signals

_POOLS: dict = {}
_local = threading.local()
LOCK = threading.Lock()  # for counters that blocks on several threads add to


def _pool(workers: int) -> ThreadPoolExecutor:
    pool = _POOLS.get(workers)
    if pool is None:
        pool = _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="smbs-lanes")
    return pool


_BESIDE: list = []  # the one thread of beside(), made on first use


@atexit.register
def _shutdown():
    for pool in list(_POOLS.values()) + _BESIDE:
        pool.shutdown(wait=False)


def beside(fn):
    """fn() on a thread of its own, one more than the pool's: a pass that would run alone on the
    calling thread (its work too small to split) runs beside the split work of another, in the
    gaps its parts leave. Its own calls do not split (nested). Returns the Future."""
    with LOCK:
        if not _BESIDE:
            _BESIDE.append(ThreadPoolExecutor(max_workers=1, thread_name_prefix="smbs-beside"))
    return _BESIDE[0].submit(_part, lambda _a, _b: fn(), 0, 0)


def nested() -> bool:
    """Whether this thread runs a part of a split run (then run does not split again)."""
    return getattr(_local, "depth", 0) > 0


def _part(call, a: int, b: int):
    signals.check()
    _local.depth = getattr(_local, "depth", 0) + 1
    try:
        return call(a, b)
    finally:
        _local.depth -= 1


def _gather(first, futures) -> list:
    """The futures' results after the calling thread's own (first: a thunk); whatever raised first
    is raised once every future is done."""
    error = None
    try:
        out = [first()]
    except BaseException as e:  # noqa: BLE001 - raised below, once the other parts have ended
        error, out = e, [None]
    for f in futures:
        try:
            out.append(f.result())
        except BaseException as e:  # noqa: BLE001
            error = error or e
            out.append(None)
    if error is not None:
        raise error
    return out


def bounds(n: int, threads: int, min_part: int) -> list:
    """Part boundaries: at most `threads` parts of at least `min_part` lanes (one part if fewer)."""
    k = max(1, min(threads, n // max(min_part, 1)))
    return [n * i // k for i in range(k + 1)]


def run(call, n: int, threads: int, min_part: int) -> list:
    """[call(a, b) for each part [a, b)], the first part on the calling thread; one part when
    called from inside a part."""
    b = bounds(n, threads, min_part)
    if len(b) == 2 or nested():
        return [call(0, n)]
    futures = [_pool(len(b) - 2).submit(_part, call, b[i], b[i + 1]) for i in range(1, len(b) - 1)]
    return _gather(lambda: _part(call, b[0], b[1]), futures)


def block_edges(n: int, size: int, min_size: int = 0) -> list:
    """Block boundaries of n lanes: blocks of `size`; with min_size, blocks that shrink towards
    the end (an eighth of what is left, between min_size and size), so that a heavy last block
    does not keep one thread busy while the others wait. They depend on n alone."""
    size = max(size, 1)
    if min_size <= 0:
        return list(range(0, n, size)) + [n]
    out, a = [0], 0
    while a < n:
        a = min(n, a + max(min_size, min(size, (n - a) // 8)))
        out.append(a)
    return out


def blocks(call, n: int, size: int, threads: int, min_size: int = 0, whole: bool = False) -> list:
    """[call(a, b) for the blocks [0, size), [size, 2 size), ... of n lanes (block_edges)], in block
    order. With more than one block and thread, each thread (the calling one included) takes
    the next block when it is done with one, and calls inside a block do not split; with one
    block, the calls inside it split over the threads as usual. whole: where the blocks would
    run in turn on this thread (one thread, or inside a block already), [call(0, n)], one call
    for all (for calls whose result does not depend on the cut: a kernel's fixed cost is paid
    once, not per block)."""
    edges = block_edges(n, size, min_size)
    k = len(edges) - 1
    if k <= 0:
        return []
    if k == 1 or threads <= 1 or nested():
        if whole:
            signals.check()
            return [call(0, n)]
        out = []
        for i in range(k):
            signals.check()
            out.append(call(edges[i], edges[i + 1]))
        return out
    out = [None] * k
    todo = itertools.count()  # next() is atomic under the GIL
    failed = []  # a block raised: the other threads take no more

    def worker(_a, _b):
        while not failed:
            i = next(todo)
            if i >= k:
                return
            try:
                signals.check()
                out[i] = call(edges[i], edges[i + 1])
            except BaseException:
                failed.append(True)
                raise

    w = min(threads, k)
    futures = [_pool(w - 1).submit(_part, worker, 0, 0) for _ in range(w - 1)]
    _gather(lambda: _part(worker, 0, 0), futures)
    return out


def add_stats(into: dict, part: dict) -> None:
    """Add the counters of a part that ran on a thread (with its own dict) to the bake's, in
    part order: numbers add, nested dicts merge, maxima (keys ending in _max) take the larger."""
    for k, v in part.items():
        if isinstance(v, dict):
            add_stats(into.setdefault(k, {}), v)
        elif k.endswith("_max"):
            into[k] = max(into.get(k, v), v)
        else:
            into[k] = into.get(k, 0) + v


_SCRATCH: list = []  # (the thread, its scratch dict) for each thread that has one (free_scratch)


def scratch(name: str, shape: tuple, dtype=float):
    """A work array of this thread's, uninitialised like np.empty, kept between calls (grown when
    too small) until free_scratch: a kernel that writes a few of a large array's pages does not
    fault in fresh ones on every call (the hand-off's records: on the glass ball's bent pass, 0.98
    -> 0.6 s of a 9 s bake). Valid until this thread's next call with the same name."""
    size = int(np.prod(shape))
    cache = getattr(_local, "scratch", None)
    if cache is None:
        cache = _local.scratch = {}
        with LOCK:
            _SCRATCH.append((weakref.ref(threading.current_thread()), cache))
    buf = cache.get(name)
    if buf is None or buf.size < size or buf.dtype != np.dtype(dtype):
        buf = cache[name] = np.empty(size, dtype)
    return buf[:size].reshape(shape)


def free_scratch() -> None:
    """Let go of every thread's scratch arrays (the end of a bake): the pool's threads outlive it,
    and the entries of threads that have ended go too."""
    with LOCK:
        for _, cache in _SCRATCH:
            cache.clear()
        _SCRATCH[:] = [(t, cache) for t, cache in _SCRATCH if (th := t()) is not None and th.is_alive()]
