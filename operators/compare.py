"""Compare Methods: the equal-time table of the open scene, in the panel.

Each chosen method bakes the scene for the same seconds (``smbs_addon.baking.compare``, the core of
``python -m smbs_addon compare``); the panel then shows, per method, its noise and the time
it needs for the same noise as the fastest. Nothing of the scene changes but the stored
report: no EXR is written, the compositor and Cycles' switches stay as they are.

It runs like a bake: in a worker thread in the interface (the panel's progress bar and Cancel
button, Esc), synchronously in background mode.
"""
from __future__ import annotations

import dataclasses
import json

import bpy

from ..ui.properties import COMPARE_ITEMS
from . import bake as B


@dataclasses.dataclass
class CompareTask:
    """ModalBake's task for Compare Methods."""
    methods: tuple
    seconds: float
    what: str = "Method comparison"

    @staticmethod
    def settings(settings):
        """The bake settings as compare takes them: one sample per pixel per batch, as Stop By
        Time does (the seconds come from the comparison, not from the bake's stop rule)."""
        return dataclasses.replace(settings, spp=settings.batches, time_budget=0.0, noise_target=0.0)

    def run(self, data, settings, progress=None, cancel=None) -> dict:
        from ..smbs_addon.baking.compare import compare, json_report

        return json_report(compare(data, list(self.methods), self.seconds, settings, cancel=cancel,
                                   bake_progress=progress))

    def finish(self, scene, prep, report: dict, core, say) -> bool:
        """Store the report on the scene (the panel draws it) and say who was fastest."""
        from ..smbs_addon.baking.compare import table_lines

        scene.smbs_caustics.compare_report = json.dumps(report, default=B._json_default)
        for message in prep.warnings:
            say({'WARNING'}, message)
        if report.get("nothing_to_bake"):
            say({'WARNING'}, f"Nothing to compare: {report['nothing_to_bake']}")
            return True
        lines = table_lines(report)
        if bpy.app.background:
            print("SMBS Caustics: " + "\n".join(lines), flush=True)
        say({'INFO'}, summary(report))
        return True


def summary(report: dict) -> str:
    """One line: the fastest method to a given noise, or why there is none."""
    rows = [r for r in report.get("rows", []) if r.get("time_for_same_error") is not None]
    if not rows:
        return (f"Compared {len(report.get('rows', []))} method(s) at {report.get('seconds', 0):g} s each; "
                "none has an error bar to price (too few batches, or biased)")
    best = min(rows, key=lambda r: r["time_for_same_error"])
    return (f"Compared at {report['seconds']:g} s each: {best['method']} reaches a given noise fastest "
            f"(\u00b1{best['error']:.1%} in {best['time_s']:.1f} s)")


def _task(props) -> CompareTask:
    """The methods in the toggles' order, and the seconds, as the panel has them."""
    return CompareTask(tuple(m for m, _, _ in COMPARE_ITEMS if m in props.compare_methods),
                       float(props.compare_seconds))


class SMBS_OT_compare_methods(B.ModalOperator, bpy.types.Operator):
    """Bake this scene with each chosen method for the same time and show their noise side by
    side: which method reaches a given noise fastest here (nothing is written or composited)"""

    bl_idname = "smbs.compare_methods"
    bl_label = "Compare Methods"
    bl_options = {'REGISTER'}

    def modal_task(self, context):
        """The task as the panel has it, or False (reported) when no method is chosen."""
        task = _task(context.scene.smbs_caustics)
        if not task.methods:
            self.report({'ERROR'}, "Compare Methods: choose at least one method")
            return False
        return task

    def execute(self, context):
        task = self.modal_task(context)
        if task is False:
            return {'CANCELLED'}
        return self.execute_task(context, task)


classes = (SMBS_OT_compare_methods,)
