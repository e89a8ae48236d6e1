"""The command line's exit codes, what a farm reads: 0 done (also for a scene with no caustic to
bake: its layer is all zero and the output says why), 1 the scene cannot be baked (the message names
the object and the problem), 2 bad arguments, 3 unreadable input or unwritable output (the previous
output is unchanged, and the message says where the result was kept), 128 + the signal's number
when a signal stopped the bake: 130 Ctrl-C (SIGINT), 143 SIGTERM, 129 SIGHUP (nothing is written;
with --keep-partial, a bake by --time or --noise writes the batches done and still exits so)."""
from __future__ import annotations

import signal

EXIT_OK, EXIT_SCENE, EXIT_USAGE, EXIT_IO, EXIT_CANCELLED = 0, 1, 2, 3, 130


EXIT_NOT_READY = 1  # prepare --check


def cancelled(signum: int = 0) -> int:
    """The exit code of a bake a signal stopped: 128 + its number (130 without one)."""
    return 128 + int(signum) if signum else EXIT_CANCELLED


EXIT_TERMINATED, EXIT_HANGUP = cancelled(signal.SIGTERM), cancelled(getattr(signal, "SIGHUP", 1))
