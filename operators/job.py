"""A bake running in a worker thread.

The thread runs only the render core (numpy and embree): the scene is exported
on the main thread before it starts, and everything that touches Blender (the
EXR, the Image, the compositor) happens on the main thread after it ends. The
main thread polls ``status()`` from a modal timer; ``cancel()`` makes the core
raise ``BakeCancelled`` at its next check (between chunks of work).

Nothing here imports bpy, so it is tested like any Python code.
"""
from __future__ import annotations

import threading
import time


class BakeJob:
    """``run(data, settings, progress=..., cancel=...)`` in a daemon thread.

    After the thread ends, exactly one of ``result`` and ``error`` is set.
    """

    def __init__(self, run, data, settings):
        self._run = run
        self.data = data
        self.settings = settings
        self.result = None
        self.error: BaseException | None = None
        self._cancel = threading.Event()
        self._finished = threading.Event()
        self._lock = threading.Lock()
        self._fraction = 0.0
        self._message = "starting"
        self._thread: threading.Thread | None = None
        self.started = 0.0

    # --- main thread
    def start(self) -> "BakeJob":
        if self._thread is not None:
            raise RuntimeError("a BakeJob runs once")
        self.started = time.monotonic()
        self._thread = threading.Thread(target=self._main, name="SMBS Caustics bake", daemon=True)
        self._thread.start()
        return self

    def cancel(self) -> None:
        self._cancel.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    @property
    def done(self) -> bool:
        return self._finished.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the thread to end; True if it has."""
        return self._finished.wait(timeout)

    def status(self) -> tuple[float, str]:
        """(fraction done in [0, 1], the core's last message)."""
        with self._lock:
            fraction, message = self._fraction, self._message
        budget = float(getattr(self.settings, "time_budget", 0.0) or 0.0)
        if budget > 0 and not self.done:  # a time-limited bake ends by the clock, not by a count
            fraction = max(fraction if fraction < 1.0 else 0.0,
                           min(0.99, (time.monotonic() - self.started) / budget))
        return fraction, message

    def elapsed(self) -> float:
        return time.monotonic() - self.started if self.started else 0.0

    # --- worker thread
    def _progress(self, fraction, message=""):
        with self._lock:
            self._fraction = min(max(float(fraction), 0.0), 1.0)
            if message:
                self._message = str(message)

    def _main(self):
        try:
            self.result = self._run(self.data, self.settings, progress=self._progress,
                                    cancel=self._cancel.is_set)
        except BaseException as e:  # handed to the main thread, which reports it
            self.error = e
        finally:
            self._finished.set()
