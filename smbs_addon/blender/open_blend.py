"""A .blend file -> ``Scene``: open it with the bpy module and export its scene (the command
line's .blend input, cli.inputs), at the frame it was saved at or at any frame of a range (opened
once, ``frame_set`` per frame: animated transforms, lights, camera, modifiers and shape keys, world),
and render the albedo its EXR's colour needs (albedo.py)."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import SceneError
from ..scene.arrays import Scene

try:
    import bpy
except ImportError:  # the command line reads .npz scenes without bpy; a .blend needs it
    raise SceneError("reading .blend files needs the bpy module (pip install bpy==5.0.1)") from None

from .albedo import diffuse_color  # noqa: E402 (after bpy, whose absence is said above)
from .export import export_scene  # noqa: E402


def open_blend(path, warn) -> Scene:
    """The Scene of the .blend file at path (its scene as saved, the file opened in place of the
    current one, without its UI); OSError where bpy cannot open it."""
    return BlendFile(path).scene_at(None, warn)


class BlendFile:
    """A .blend file opened once (in place of the current one, without its UI), its scene exported at
    any frame; OSError where bpy cannot open it."""

    def __init__(self, path):
        try:
            bpy.ops.wm.open_mainfile(filepath=str(Path(path).resolve()), load_ui=False)
        except RuntimeError as err:
            raise OSError(f"cannot open '{path}' as a .blend file: {str(err).strip().splitlines()[-1]}") from None
        self.path = str(path)

    @property
    def scene(self):
        return bpy.context.scene

    def frame_range(self) -> tuple[int, int, int]:
        """The scene's (first frame, last frame, step)."""
        sc = self.scene
        return int(sc.frame_start), int(sc.frame_end), int(sc.frame_step)

    @property
    def frame_current(self) -> int:
        return int(self.scene.frame_current)

    def scene_at(self, frame, warn) -> Scene:
        """The Scene at frame (None: at the frame the file is at, as saved)."""
        if frame is not None:
            self.scene.frame_set(int(frame))
        return export_scene(self.scene, warn=warn)

    def albedo(self, camera):
        """Cycles' Diffuse Color pass at the current frame (albedo.diffuse_color)."""
        return diffuse_color(self.scene, camera)
