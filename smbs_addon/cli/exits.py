"""The command line's exit codes, what a farm reads: 0 done (also for a scene with no caustic to
bake: its layer is all zero and the output says why), 1 the scene cannot be baked (the message names
the object and the problem), 2 bad arguments, 3 unreadable input or unwritable output, 130
cancelled (Ctrl-C, SIGTERM, SIGHUP)."""
from __future__ import annotations

EXIT_OK, EXIT_SCENE, EXIT_USAGE, EXIT_IO, EXIT_CANCELLED = 0, 1, 2, 3, 130


EXIT_NOT_READY = 1  # prepare --check
