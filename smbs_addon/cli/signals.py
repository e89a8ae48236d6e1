"""The command line's signals: SIGINT (Ctrl-C), SIGTERM and SIGHUP (a farm stopping a job, a
closed terminal) stop a bake cleanly.

A signal only sets the stop flag (core/signals.py), which the bake polls between blocks of lanes:
it never raises inside compiled code (Python's own Ctrl-C raised KeyboardInterrupt in whatever a
kernel's caller was doing, and numba's dispatcher turned that into a SystemError). The flag is set
from a thread of its own, woken by the signal through Python's wakeup file descriptor, so it is set
at once even while the main thread is inside a kernel that holds it for long. The bake then ends
with BakeCancelled within one block; the command line removes nothing and replaces nothing (the
outputs are written whole or not at all: io/exr.save_outputs) and exits 128 + the signal's number
(exits.py). A second signal stops at once: the temporary files of a write under way are removed
and the process exits with the same code.
"""
from __future__ import annotations

import os
import signal
import sys
import threading

from ..core import signals
from ..io.exr import remove_pending
from .exits import cancelled

HANDLED = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


def _ignore(signum, frame):  # the watcher thread does the work (a Python handler must be set for it)
    return None


def _on_signal(signum: int) -> None:
    n = signals.request(signum)
    first = signals.requested()
    if n == 1:
        print(f"\nsmbs_addon: {signals.name(signum)}: stopping the bake (again to stop at once)",
              file=sys.stderr, flush=True)
    else:
        remove_pending()
        print(f"smbs_addon: {signals.name(signum)} again: stopped at once, nothing written",
              file=sys.stderr, flush=True)
        os._exit(cancelled(first))


def _direct(signum, frame):  # where no wakeup fd can be had (Windows): the flag, from the main thread
    _on_signal(signum)


def _watch(fd: int) -> None:
    while True:
        try:
            data = os.read(fd, 64)
        except OSError:
            return
        if not data:
            os.close(fd)
            return
        for signum in data:
            if signum in HANDLED:
                _on_signal(signum)


def install():
    """Handle SIGINT, SIGTERM and SIGHUP as above; returns a function that puts back what was there
    (or None where this is not the main thread: signals are then left alone)."""
    if threading.current_thread() is not threading.main_thread():
        return None
    signals.clear()
    try:
        r, w = os.pipe()
        os.set_blocking(w, False)
        old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    except (OSError, ValueError):  # Windows: a wakeup fd must be a socket; the flag from the handler instead
        r = w = old_fd = None
    old = {s: signal.signal(s, _ignore if w is not None else _direct) for s in HANDLED}
    if w is not None:
        threading.Thread(target=_watch, args=(r,), name="smbs-signals", daemon=True).start()

    def restore():
        if w is not None:
            signal.set_wakeup_fd(old_fd)
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)
        if w is not None:
            os.close(w)  # the watcher reads the end of the pipe and returns
        signals.clear()

    return restore
