"""A stop asked for from outside the bake (a signal: Ctrl-C, SIGTERM, SIGHUP), as a flag.

Whoever catches the signal (the command line: cli/signals.py) sets the flag with request(); it
never raises inside compiled code. The bake polls it where it hands out work: before every block
of lanes (core/lanes.py) and every chunk (baking/job.Progress.check), so it stops within one
block of a kernel's lanes, with BakeCancelled; nothing is half-written (io/exr.save_outputs).
"""
from __future__ import annotations

import signal
import threading

from .errors import BakeCancelled

_lock = threading.Lock()
_state = {"signum": 0, "count": 0, "acknowledged": False}


def request(signum: int) -> int:
    """Ask the bake to stop because of signal signum; returns how many stops were asked so far."""
    with _lock:
        if not _state["signum"]:
            _state["signum"] = int(signum)
        _state["count"] += 1
        return _state["count"]


def requested() -> int:
    """The signal that asked for a stop (the first one), or 0."""
    return _state["signum"]


def clear() -> None:
    with _lock:
        _state.update(signum=0, count=0, acknowledged=False)


def acknowledge() -> None:
    """The stop is taken (a bake that keeps its batches done): check() no longer raises; requested()
    still says which signal came, and a further signal counts on (request)."""
    _state["acknowledged"] = True


def name(signum: int) -> str:
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def check() -> None:
    """Raise BakeCancelled if a stop was asked for."""
    s = _state["signum"]
    if s and not _state["acknowledged"]:
        raise BakeCancelled(f"stopped by {name(s)}", signum=s)
