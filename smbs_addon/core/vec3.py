"""3-vectors as tuples inside compiled code: held in registers, never allocated.

The one dot product, tangent frame and array-row read every kernel and shading function calls
(LLVM inlines them into each caller's machine code).
"""
from __future__ import annotations

import math

from numba import njit

from .jit import JIT


@njit(**JIT)
def dot1(a, b):
    """The dot product of two 3-tuples (optics and kernels call this one: LLVM inlines it)."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**JIT)
def frame1(n):
    """Two unit tangents completing the unit n to an orthonormal frame (Duff et al. 2017)."""
    s = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (s + n[2])
    b = n[0] * n[1] * a
    return (1.0 + s * n[0] * n[0] * a, s * b, -s * n[0]), (b, s + n[1] * n[1] * a, -n[1])


@njit(**JIT)
def row3(a, i):
    """Row i of an (N, 3) array as a 3-tuple."""
    return (a[i, 0], a[i, 1], a[i, 2])


# ------------------------------------------------------------------ 3-vectors as tuples
# These and the keyed random numbers are called, not inline="always" (jit.py: LLVM inlines them)
@njit(**JIT)
def cols3(a, i, off):
    return (a[i, off], a[i, off + 1], a[i, off + 2])


@njit(**JIT)
def vertex_cols3(F, i, j, off):
    return (F[i, j, off], F[i, j, off + 1], F[i, j, off + 2])


@njit(**JIT)
def add3(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@njit(**JIT)
def sub3(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@njit(**JIT)
def scale3(s, a):
    return (s * a[0], s * a[1], s * a[2])


@njit(**JIT)
def div3(a, s):
    return (a[0] / s, a[1] / s, a[2] / s)


@njit(**JIT)
def neg3(a):
    return (-a[0], -a[1], -a[2])


@njit(**JIT)
def cross3(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(**JIT)
def normalize3(a):
    """vec.normalize: times 1/|a|, zero stays zero."""
    n = math.sqrt(dot1(a, a))
    inv = 1.0 / n if n > 0 else 0.0
    return (a[0] * inv, a[1] * inv, a[2] * inv)


@njit(**JIT)
def max_nan(a, b):
    """np.maximum: NaN propagates."""
    if a != a:
        return a
    return a if a >= b else b
