"""Lanes split over threads: one persistent pool per thread count, parts in lane order.

embree's ``run`` and the numba kernels (nogil) release the GIL, so a batch of lanes cut into
contiguous parts runs on several cores. Each part's result is the same whichever thread runs it,
and parts are joined in order: the image does not depend on the thread count.
"""
from __future__ import annotations

import atexit
from concurrent.futures import ThreadPoolExecutor

_POOLS: dict = {}


def _pool(workers: int) -> ThreadPoolExecutor:
    pool = _POOLS.get(workers)
    if pool is None:
        pool = _POOLS[workers] = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="smbs-lanes")
    return pool


@atexit.register
def _shutdown():
    for pool in _POOLS.values():
        pool.shutdown(wait=False)


def bounds(n: int, threads: int, min_part: int) -> list:
    """Part boundaries: at most `threads` parts of at least `min_part` lanes (one part if fewer)."""
    k = max(1, min(threads, n // max(min_part, 1)))
    return [n * i // k for i in range(k + 1)]


def run(call, n: int, threads: int, min_part: int) -> list:
    """[call(a, b) for each part [a, b)], the first part on the calling thread."""
    b = bounds(n, threads, min_part)
    if len(b) == 2:
        return [call(0, n)]
    futures = [_pool(len(b) - 2).submit(call, b[i], b[i + 1]) for i in range(1, len(b) - 1)]
    first = call(b[0], b[1])
    return [first] + [f.result() for f in futures]
