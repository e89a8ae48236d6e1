"""Which code made a file: the package's version and a digest of the render core's source.

A frame of a range is skipped on a second run, and shards are merged, only where their EXRs say the
same code made them (io.exr.exr_metadata's ``code``): the version alone does not change with every
edit of the code, the source digest does. The digest is of the ``.py`` files of ``smbs_addon/``, in
the order of their paths, so it is the same on every machine for the same source (a git checkout, an
installed extension) and costs a few milliseconds, once per process.
"""
from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

VERSION = "0.1.0"
CORE = Path(__file__).resolve().parent.parent


@lru_cache(maxsize=1)
def code_version() -> str:
    """``VERSION+<12 hex digits of the source digest>``."""
    h = hashlib.sha1()
    for p in sorted(CORE.rglob("*.py")):
        h.update(p.relative_to(CORE).as_posix().encode())
        h.update(b"\0")
        h.update(p.read_bytes())
    return f"{VERSION}+{h.hexdigest()[:12]}"
