"""The command line, ``python -m smbs_addon``, in a subprocess from the repository root."""
from __future__ import annotations

import os
import subprocess
import sys

from . import ROOT


def run(*args, timeout=120):
    """python -m smbs_addon ARGS (each str()'d), the repository first on PYTHONPATH: the finished process."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "smbs_addon", *map(str, args)], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=timeout)


def one_error_line(proc) -> str:
    """The one line a failed command writes on stderr (asserted: one line, ``smbs_addon: error: ...``,
    no traceback)."""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got:\n{proc.stderr}"
    assert lines[0].startswith("smbs_addon: error: "), lines[0]
    assert "Traceback" not in proc.stderr
    return lines[0]
