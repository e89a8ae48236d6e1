"""Calling kernels with long tuples without numba typing them on every call.
"""
from __future__ import annotations


import numpy as np



# numpy's flag bits that change an array's numba type: C_CONTIGUOUS, F_CONTIGUOUS, ALIGNED, WRITEABLE
_TYPE_FLAGS = 0x1 | 0x2 | 0x100 | 0x400


def _arg_key(v):
    """What of v decides its numba type, cheaply: dtype, ndim and layout flags of arrays,
    recursively in tuples and named tuples (records.py's records: their class and their fields'
    keys), the Python type of anything else (bool, int, float)."""
    t = type(v)
    if t is np.ndarray:
        return (v.dtype.char, v.ndim, v.flags.num & _TYPE_FLAGS)
    if t is tuple:
        return tuple(map(_arg_key, v))
    if issubclass(t, tuple):  # a named tuple: numba types it by its class and its fields
        return (t, tuple(map(_arg_key, v)))
    return t


class TypedOnce:
    """A kernel called with tuples and records (the walk's settings, lane and state, passed as one
    argument each) without numba typing them on every call. numba's dispatcher types a tuple of
    more than 4 items in Python on each call (its C fingerprint cache gives up on them): 0.1-0.5
    ms per call, under the GIL, 1.0 s of a 4.9 s bake (glass sphere 256^2, SMS) before this.
    Here the compiled code for an argument key (_arg_key) is looked up once through the
    dispatcher and then called directly (numba's own wrapper: it unboxes the arguments, releases
    the GIL as nogil asks, raises as the kernel raises). A key whose types numba would convert
    rather than match exactly keeps going through the dispatcher."""

    def __init__(self, dispatcher):
        self.dispatcher = dispatcher
        self.__doc__ = dispatcher.__doc__
        self._entries: dict = {}

    def __call__(self, *args):
        key = _arg_key(args)
        entry = self._entries.get(key)
        if entry is not None:
            return entry(*args)
        out = self.dispatcher(*args)  # types, compiles or loads from the cache
        if key not in self._entries:
            sig = tuple(self.dispatcher.typeof_pyval(a) for a in args)
            cres = self.dispatcher.overloads.get(sig)
            self._entries[key] = cres.entry_point if cres is not None else self.dispatcher
        return out
