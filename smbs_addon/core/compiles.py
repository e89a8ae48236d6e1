"""What compiling the kernels costs a bake: they compile with numba on their first use after
installing or updating (jit.py) and load from the disk cache afterwards.

Not in jit.py: an edit of jit.py changes the stamp of every cached kernel (jit._FILES).
"""
from __future__ import annotations

import time


def counted(n: int, noun: str) -> str:
    """'1 kernel', '31 kernels', '2 processes': what the messages about compiling count."""
    return f"{n} {noun}" if n == 1 else f"{n} {noun}{'es' if noun.endswith('s') else 's'}"


class CompileWatch:
    """The time numba spends compiling this package's kernels while the watch is on (with ... as
    watch): a kernel compiles on its first use after installing or updating and is loaded from the
    disk cache afterwards, so a bake that compiles pays a cost that later bakes do not.

    seconds and kernels count the outermost compiles only (a kernel's helpers compile inside it);
    loads from the cache do not count. on_start() is called when a compile begins after none was
    running, on_end() when it ends, on the thread that compiles (a worker's, in a threaded bake).
    numba compiles one function at a time in a process (its global compiler lock), so compiles
    never overlap; a compile by another thread of the process while the watch is on counts too."""

    def __init__(self, on_start=None, on_end=None):
        self.seconds = 0.0
        self.kernels = 0
        self._on_start, self._on_end = on_start, on_end
        self._depth = 0
        self._t = 0.0
        self._listener = None

    def _start(self, ev):
        if self._depth == 0:
            self._t = time.perf_counter()
            if self._on_start is not None:
                self._on_start()
        self._depth += 1

    def _end(self, ev):
        self._depth = max(self._depth - 1, 0)
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._t
            self.kernels += 1
            if self._on_end is not None:
                self._on_end()

    def __enter__(self):
        from numba.core import event

        watch = self

        class Listener(event.Listener):
            def on_start(self, ev):
                watch._start(ev)

            def on_end(self, ev):
                watch._end(ev)

        self._listener = Listener()
        event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc):
        from numba.core import event

        event.unregister("numba:compile", self._listener)
        self._listener = None
        return False

    def now(self) -> float:
        """Seconds compiled so far, a compile under way included."""
        running = time.perf_counter() - self._t if self._depth else 0.0
        return self.seconds + running
