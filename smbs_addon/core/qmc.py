"""Stratified sample dimensions: Sobol' points, Owen-scrambled by a hash (Burley 2020, "Practical
Hash-based Owen Scrambling"), one scramble per film cell and replicate.

A film cell's eye samples within one replicate of a bake (baking/job.Job.strata: batch b continues
replicate b mod batches) are one scrambled Sobol' sequence: the cell's sample g there takes the
sequence's point g, so its first 2^m samples are a (0, m, 2)-net in each pair of dimensions (the
pixel's jitter, the light sample's, the first diffuse bounce's, the light sample's after it), and so
is each run of 2^m samples from a multiple of 2^m. The scrambles, keyed by the cell and the
replicate's stream, make every point uniform on [0, 1)^DIMS (every estimate stays unbiased) and the
cells' and replicates' sequences independent of each other. Within a replicate the samples are not
independent (they fill each other's gaps), so the error bar reads the spread between replicates
(trace/film.Film.use_replicates), not between batches.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

DIMS = 8  # in pairs: the pixel's jitter (x, y), then the path's (PATH_DIMS)
# the path's columns (after the jitter's two): the light sample's two uniforms at the receiver, the first
# diffuse bounce's direction from it (paths/gather: the caustic after a diffuse bounce), and the light
# sample's at the vertex that bounce meets
PATH_DIMS = DIMS - 2
LIGHT, BOUNCE, BOUNCE_LIGHT = slice(0, 2), slice(2, 4), slice(4, 6)
BITS = 32


def _directions() -> np.ndarray:
    """(2, BITS) uint32 direction numbers v_k of Sobol's first two dimensions: van der Corput's, and
    Joe and Kuo's second (primitive polynomial x + 1, m_1 = 1: v_k = v_(k-1) xor v_(k-1) >> 1)."""
    v = np.zeros((2, BITS), np.uint64)
    v[0] = [1 << (BITS - 1 - k) for k in range(BITS)]
    v[1, 0] = 1 << (BITS - 1)
    for k in range(1, BITS):
        v[1, k] = v[1, k - 1] ^ (v[1, k - 1] >> np.uint64(1))
    return v.astype(np.uint32)


_V = _directions()
# per dimension and byte of the index, the XOR of the direction numbers its set bits pick: a point is
# four lookups (the index's 32 bits walked one by one cost 1.2 s of a 7 s bake)
_BYTES = np.array([[[np.bitwise_xor.reduce(np.where((b >> np.arange(8)) & 1 == 1, _V[d, 8 * k:8 * k + 8], 0))
                     for b in range(256)] for k in range(4)] for d in range(len(_V))], np.uint32)


def sobol(index: np.ndarray) -> np.ndarray:
    """(N, 2) uint32 Sobol' points of the (N,) uint32 indices (not scrambled)."""
    index = np.asarray(index).astype(np.uint32)
    out = np.empty((len(index), len(_V)), np.uint32)
    for d in range(len(_V)):
        t = _BYTES[d]
        out[:, d] = t[0][index & 0xFF] ^ t[1][(index >> 8) & 0xFF] ^ t[2][(index >> 16) & 0xFF] ^ t[3][index >> 24]
    return out


def _reverse_bits(x: np.ndarray) -> np.ndarray:
    x = x.astype(np.uint32)
    x = ((x >> 1) & 0x55555555) | ((x & 0x55555555) << 1)
    x = ((x >> 2) & 0x33333333) | ((x & 0x33333333) << 2)
    x = ((x >> 4) & 0x0F0F0F0F) | ((x & 0x0F0F0F0F) << 4)
    x = ((x >> 8) & 0x00FF00FF) | ((x & 0x00FF00FF) << 8)
    return ((x >> 16) | (x << 16)).astype(np.uint32)


def _laine_karras(x: np.ndarray, seed: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):
        x = (x + seed).astype(np.uint32)
        for c in (0x6C50B47C, 0xB82F1E52, 0xC7AFE638, 0x8D22F6E6):
            x ^= (x * np.uint32(c)).astype(np.uint32)
    return x


def owen(x: np.ndarray, seed: np.ndarray) -> np.ndarray:
    """Nested uniform scramble of the 32-bit x, keyed by seed (each bit flipped by a hash of the
    bits above it)."""
    return _reverse_bits(_laine_karras(_reverse_bits(x), seed))


def _hash(x: np.ndarray) -> np.ndarray:
    """A 32-bit integer hash (Wellons' lowbias32)."""
    with np.errstate(over="ignore"):
        x = np.asarray(x).astype(np.uint32)
        x ^= x >> 16
        x = (x * np.uint32(0x7FEB352D)).astype(np.uint32)
        x ^= x >> 15
        x = (x * np.uint32(0x846CA68B)).astype(np.uint32)
        x ^= x >> 16
    return x


def after_bounce(path_u: np.ndarray) -> np.ndarray:
    """The path's uniforms (M, PATH_DIMS) as a vertex after x0's diffuse bounce reads them: its light
    sample takes the BOUNCE_LIGHT pair (at every later diffuse vertex the same numbers: each vertex's
    estimate is unbiased on its own)."""
    out = path_u.copy()
    out[:, LIGHT] = path_u[:, BOUNCE_LIGHT]
    return out


@dataclass(frozen=True)
class Strata:
    """A batch's stratified eye samples: its replicate's scramble seed (from the bake's STRATA
    stream of that replicate) and its round in the replicate, whose samples continue each cell's
    sequence."""
    seed: int
    round: int


class StratifiedDraws:
    """A random generator's stand-in whose first random(n) draws are the columns of u (N, k): the
    stratified dimensions a light sample takes (shading.light_samples draws its uniforms in order);
    further draws, and any other method, go to rng."""

    def __init__(self, u: np.ndarray, rng):
        self._u, self._k, self._rng = u, 0, rng

    def random(self, size=None):
        if self._k < self._u.shape[1] and isinstance(size, (int, np.integer)) and size == len(self._u):
            self._k += 1
            return self._u[:, self._k - 1].copy()
        return self._rng.random(size)

    def __getattr__(self, name):
        return getattr(self._rng, name)


def cell_points(cell: np.ndarray, index: np.ndarray, seed: int) -> np.ndarray:
    """(N, DIMS) uniforms in [0, 1): point index of film cell cell's scrambled sequence (seed: the
    bake's stream). Each pair of dimensions is Sobol's first two, its own shuffle of the index
    (an Owen scramble: a run of 2^m from a multiple of 2^m stays one) and its own scramble of the
    digits: a (0, m, 2)-net per pair, the pairs padded together at random (Burley 2020)."""
    key = _hash(np.asarray(cell, np.uint64).astype(np.uint32) ^ np.uint32(seed & 0xFFFFFFFF))
    index = np.asarray(index).astype(np.uint32)
    u = np.empty((len(index), DIMS))
    for pair in range(DIMS // 2):
        x = sobol(owen(index, _hash(key + np.uint32(2 * pair + 1))))
        for k in range(2):
            d = 2 * pair + k
            u[:, d] = owen(x[:, k], _hash(key ^ np.uint32((0x9E3779B9 * (d + 1)) & 0xFFFFFFFF))) * (1.0 / 2**32)
    return u
