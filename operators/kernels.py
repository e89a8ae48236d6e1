"""Prepare Kernels: compile the render core's kernels now, not in the first bake.

The kernels compile with numba on their first use after installing or updating the extension
and load from a disk cache afterwards (smbs_addon/jit.py); the first bake otherwise spends a
few minutes compiling (its statistics say how long: "Of Which Compiling"). This operator makes
the tiny bakes of ``smbs_addon.baking.prepare`` in one process of Blender's Python per core, each
importing the core under the name Blender imports the extension by, so that Blender's bakes find
them (numba's cache is kept per name: the CLI's ``python -m smbs_addon prepare`` compiles those of
the command line). Nothing of the scene is read or changed.

In the interface it runs like a bake (a worker thread, the panel's progress bar and Cancel
button, Esc); in background mode synchronously: on a farm node,
``blender -b --python-expr "import bpy; bpy.ops.smbs.prepare_kernels()"``.
"""
from __future__ import annotations

import dataclasses
import time

import bpy

from . import bake as B

STATE_RECHECK_S = 10.0  # the panel redraws often: prepare.ready() is read at most this often
_state = {"at": -1e9, "ready": None}


def state() -> bool | None:
    """Whether the kernels are compiled for this machine (smbs_addon.baking.prepare.ready: True, False, None
    for no telling), read afresh at most every STATE_RECHECK_S seconds and after Prepare Kernels."""
    now = time.monotonic()
    if now - _state["at"] > STATE_RECHECK_S:
        from ..smbs_addon.baking import prepare

        _state["ready"], _state["at"] = prepare.ready(), now
    return _state["ready"]


def forget_state() -> None:
    _state["at"] = -1e9


@dataclasses.dataclass
class PrepareTask:
    """ModalBake's task for Prepare Kernels."""
    what: str = "Kernel preparation"
    exports: bool = False  # no scene to export: ModalBake starts it without one

    @staticmethod
    def run(data, settings, progress=None, cancel=None) -> dict:
        from ..smbs_addon.baking import prepare

        # one process per core, each of Blender's Python importing the core under this name: the
        # interface stays free while they compile (the worker thread only waits for them)
        return prepare.prepare(progress=progress, cancel=cancel)

    @staticmethod
    def finish(scene, prep, result: dict, core, say) -> bool:
        forget_state()
        if bpy.app.background:
            print(message(result), flush=True)
        say({'INFO'}, message(result))
        return True


def message(result: dict) -> str:
    from ..smbs_addon.core.compiles import counted

    if not result["kernels"]:
        return "SMBS Caustics: the kernels were compiled already; bakes load them from the cache"
    return (f"SMBS Caustics: compiled {counted(result['kernels'], 'kernel')} in {result['seconds']:.0f} s; "
            f"bakes on this machine load them from the cache")


class SMBS_OT_prepare_kernels(B.ModalOperator, bpy.types.Operator):
    """Compile the caustic baker's kernels for this machine now (a few minutes, once after
    installing or updating), so that the first bake does not"""

    bl_idname = "smbs.prepare_kernels"
    bl_label = "Prepare Kernels"
    bl_options = {'REGISTER'}

    def modal_task(self, context):
        return PrepareTask()

    def execute(self, context):
        return self.execute_task(context, PrepareTask())


classes = (SMBS_OT_prepare_kernels,)
