"""The command line's files: the input scene (.npz, or a .blend opened with bpy) and the outputs' checks."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import SceneError
from ..io.exr import check_output
from ..scene.arrays import Scene


class NpzInput:
    """An exported scene: one frame, and no Cycles to render an albedo with."""

    def __init__(self, path):
        self.path = str(path)
        self.scene = Scene.load(path)
        self.frame_current = None

    def frame_range(self):
        return None

    def scene_at(self, frame, warn):
        return self.scene

    def albedo(self, camera):
        return None


def _check_input(path: str) -> Path:
    p = Path(path)
    if p.is_dir():
        raise IsADirectoryError(f"input '{path}' is a folder, not a .blend or .npz file")
    if not p.exists():
        raise FileNotFoundError(f"input '{path}' does not exist")
    if not p.is_file():
        raise OSError(f"input '{path}' is not a file")
    if p.suffix.lower() not in (".npz", ".blend"):
        raise SceneError(f"input '{path}': expected a .blend or .npz file")
    return p


def open_input(path: str):
    """The input: NpzInput, or a blender.open_blend.BlendFile for a .blend."""
    if _check_input(path).suffix.lower() == ".npz":
        return NpzInput(path)
    # imported here, not at the top: bpy takes seconds to load and an .npz input does not need
    # it (without bpy, this import raises SceneError saying so)
    from ..blender.open_blend import BlendFile

    return BlendFile(path)


def load_input(path: str, warn=print):
    """A Scene from a .npz or a .blend (the latter through the bpy module), at the frame it was saved at."""
    return open_input(path).scene_at(None, warn)


def check_writable(path: Path):
    """Refuse, before any work, an output that cannot be written (io.exr.check_output)."""
    check_output(path)
