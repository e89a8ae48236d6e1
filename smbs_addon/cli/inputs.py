"""The command line's files: the input scene (.npz, or a .blend opened with bpy) and the outputs' checks."""
from __future__ import annotations

import os
from pathlib import Path

from ..core.errors import SceneError
from ..scene.arrays import Scene


def load_input(path: str, warn=print):
    """A Scene from a .npz or a .blend (the latter through the bpy module)."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"input '{path}' does not exist")
    if p.suffix.lower() == ".npz":
        return Scene.load(p)
    if p.suffix.lower() == ".blend":
        # imported here, not at the top: bpy takes seconds to load and an .npz input does not need
        # it (without bpy, this import raises SceneError saying so)
        from ..blender.open_blend import open_blend

        return open_blend(path, warn)
    raise SceneError(f"input '{path}': expected a .blend or .npz file")


def check_writable(path: Path):
    parent = path.parent if str(path.parent) else Path(".")
    if parent.exists() and not parent.is_dir():
        raise OSError(f"output folder '{parent}' is a file")
    if not parent.is_dir():
        raise OSError(f"output folder '{parent}' does not exist")
    if not os.access(parent, os.W_OK):
        raise OSError(f"output folder '{parent}' is not writable")
    if path.is_dir():
        raise OSError(f"output '{path}' is a folder")
