"""Lanes split over threads: one persistent pool per thread count, parts in lane order.

embree's ``run`` and the numba kernels (nogil) release the GIL, so a batch of lanes cut into
contiguous parts runs on several cores. Each part's result is the same whichever thread runs it,
and parts are joined in order: the image does not depend on the thread count.

A part can be a whole stream of work (walk.newton_walk and pool.bernoulli_trials cut their
lanes into one stream per thread, each with its own Python loop, so one stream's Python work
overlaps the other's kernels and rays). Inside a part, ``run`` does not split again: the
stream's kernel and intersect calls run on its own thread.
"""
from __future__ import annotations

import atexit
import threading
from concurrent.futures import ThreadPoolExecutor

_POOLS: dict = {}
_local = threading.local()
LOCK = threading.Lock()  # for counters that streams on several threads add to


def _pool(workers: int) -> ThreadPoolExecutor:
    pool = _POOLS.get(workers)
    if pool is None:
        pool = _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="smbs-lanes")
    return pool


@atexit.register
def _shutdown():
    for pool in _POOLS.values():
        pool.shutdown(wait=False)


def nested() -> bool:
    """Whether this thread runs a part of a split run (then run does not split again)."""
    return getattr(_local, "depth", 0) > 0


def _part(call, a: int, b: int):
    _local.depth = getattr(_local, "depth", 0) + 1
    try:
        return call(a, b)
    finally:
        _local.depth -= 1


def bounds(n: int, threads: int, min_part: int) -> list:
    """Part boundaries: at most `threads` parts of at least `min_part` lanes (one part if fewer)."""
    k = max(1, min(threads, n // max(min_part, 1)))
    return [n * i // k for i in range(k + 1)]


def splits(n: int, threads: int, min_part: int) -> bool:
    """Whether run(call, n, threads, min_part) would cut the lanes into parts."""
    return not nested() and len(bounds(n, threads, min_part)) > 2


def run(call, n: int, threads: int, min_part: int) -> list:
    """[call(a, b) for each part [a, b)], the first part on the calling thread; one part when
    called from inside a part."""
    if not splits(n, threads, min_part):
        return [call(0, n)]
    b = bounds(n, threads, min_part)
    futures = [_pool(len(b) - 2).submit(_part, call, b[i], b[i + 1]) for i in range(1, len(b) - 1)]
    first = _part(call, b[0], b[1])
    return [first] + [f.result() for f in futures]
