"""A .blend file -> ``Scene``: open it with the bpy module and export its scene (the command
line's .blend input, cli.inputs.load_input)."""
from __future__ import annotations

from pathlib import Path

from ..core.errors import SceneError
from ..scene.arrays import Scene

try:
    import bpy
except ImportError:  # the command line reads .npz scenes without bpy; a .blend needs it
    raise SceneError("reading .blend files needs the bpy module (pip install bpy==5.0.1)") from None

from .export import export_scene  # noqa: E402 (after bpy, whose absence is said above)


def open_blend(path, warn) -> Scene:
    """The Scene of the .blend file at path (its scene as saved, the file opened in place of the
    current one, without its UI); OSError where bpy cannot open it."""
    try:
        bpy.ops.wm.open_mainfile(filepath=str(Path(path).resolve()), load_ui=False)
    except RuntimeError as err:
        raise OSError(f"cannot open '{path}' as a .blend file: {str(err).strip().splitlines()[-1]}") from None
    return export_scene(bpy.context.scene, warn=warn)
