"""What the fault-injection tests share: the command line in a subprocess (with a fault set up before
it starts: a file size limit, dropped privileges), a tiny scene saved as .npz, and the checks that
nothing was lost (the previous output's bytes, no temporary file left beside it)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from testkit import scenes

# SMBS_FAULTS_ROOT: run the command line of another checkout (to see a case fail before its fix)
ROOT = Path(os.environ.get("SMBS_FAULTS_ROOT") or Path(__file__).resolve().parents[1])


def env(**extra) -> dict:
    e = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    e.update({k: v for k, v in extra.items() if v is not None})
    for k, v in extra.items():
        if v is None:
            e.pop(k, None)
    return e


def command(*args) -> list:
    return [sys.executable, "-m", "smbs_addon", *map(str, args)]


def run(*args, timeout=300, preexec_fn=None, environ=None, prefix=(), cwd=ROOT):
    """The command line with args, to its end: the CompletedProcess (text)."""
    return subprocess.run([*prefix, *command(*args)], cwd=cwd, env=environ or env(), capture_output=True,
                          text=True, timeout=timeout, preexec_fn=preexec_fn)


def start(*args, environ=None):
    """The command line with args, running: a Popen whose stderr is read line by line (lines())."""
    return subprocess.Popen(command(*args), cwd=ROOT, env=environ or env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, bufsize=1)


def save_mirror(path: Path, resolution=(32, 24)) -> Path:
    scenes.mirror_scene(resolution=resolution).save(path)
    return path


def previous_output(folder: Path, name="layer.exr") -> tuple[Path, bytes]:
    """A good EXR of an earlier bake (any image: what must survive is its bytes) and its bytes."""
    from smbs_addon.io.exr import write_exr, write_json

    out = folder / name
    write_exr(out, np.full((24, 32, 3), 0.125, np.float32), {"method": "earlier"})
    write_json(out.with_suffix(".json"), {"earlier": True})
    return out, out.read_bytes()


def temporaries(folder: Path) -> list:
    """Files a write leaves behind when it is cut short (the temporaries are dot files)."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") or ".tmp" in p.name)


def assert_nothing_lost(out: Path, before: bytes, json_before: bytes | None = None):
    assert out.read_bytes() == before, "the previous EXR changed"
    if json_before is not None:
        assert out.with_suffix(".json").read_bytes() == json_before, "the previous statistics changed"
    assert temporaries(out.parent) == [], "a temporary file was left beside the output"


def assert_no_traceback(proc_or_text):
    text = proc_or_text if isinstance(proc_or_text, str) else proc_or_text.stderr
    for word in ("Traceback", "KeyboardInterrupt", "SystemError"):
        assert word not in text, text


def signal_after(proc, signum, wait_for, delay=0.0, timeout=240.0) -> tuple[str, str]:
    """Read proc's stderr until a line contains wait_for, wait delay seconds, send signum; then read
    to the end (at most timeout seconds: a bake that does not stop fails here). (stdout, stderr)."""
    seen = []
    deadline = time.monotonic() + timeout
    for line in proc.stderr:
        seen.append(line)
        if wait_for in line:
            break
        assert time.monotonic() < deadline, "the bake never got there: " + "".join(seen)
    time.sleep(delay)
    proc.send_signal(signum)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"still running {timeout} s after {signal.Signals(signum).name}:\n{''.join(seen)}{err}")
    return out, "".join(seen) + err
