"""The command line's files: the input scene (.npz, or a .blend opened with bpy) and the outputs' checks."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import SceneError
from ..io.exr import check_output
from ..scene.arrays import Scene


def load_input(path: str, warn=print):
    """A Scene from a .npz or a .blend (the latter through the bpy module)."""
    p = Path(path)
    if p.is_dir():
        raise IsADirectoryError(f"input '{path}' is a folder, not a .blend or .npz file")
    if not p.exists():
        raise FileNotFoundError(f"input '{path}' does not exist")
    if not p.is_file():
        raise OSError(f"input '{path}' is not a file")
    if p.suffix.lower() == ".npz":
        return Scene.load(p)
    if p.suffix.lower() == ".blend":
        # imported here, not at the top: bpy takes seconds to load and an .npz input does not need
        # it (without bpy, this import raises SceneError saying so)
        from ..blender.open_blend import open_blend

        return open_blend(path, warn)
    raise SceneError(f"input '{path}': expected a .blend or .npz file")


def check_writable(path: Path):
    """Refuse, before any work, an output that cannot be written (io.exr.check_output)."""
    check_output(path)
