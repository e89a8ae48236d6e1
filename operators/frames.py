"""Bake Frame Range: the caustic layer of every frame of the scene's frame range (or a custom one), as
an image sequence in the compositor, so that rendering the animation composites each frame with its
own layer.

The frames are baked one after another: each is exported on the main thread at its frame
(``frame_set``), baked in the worker thread of a bake (BakeJob) and written on the main thread, to the
Output path with a run of # for the frame (``//caustics.exr`` -> ``//caustics_####.exr``, Blender's
convention) and its statistics beside it, whole or not at all. Cancel (the panel's button, Esc) stops
the frame under way, which writes nothing; the frames done are kept. At the end, or when cancelled,
the layer in the compositor is the image sequence of the frames done (composite.apply_sequence) and
the scene is back at the frame it was at. Bake Caustics on one frame of it later replaces only that
frame's file (bake.prepare). In background mode ``execute()`` runs the same steps synchronously.
"""
from __future__ import annotations

import time

import bpy

from .bake import (LAYER_NAME, ModalBake, ModalOperator, _Progress, _running, albedo_path, conclude, free_to_bake,
                   frames_pattern, load_core, plain_stats, prepare, report_failure, resolve_output_path, run_modal,
                   write_layer)
from .job import BakeJob


def range_frames(scene) -> list:
    """The frames to bake: the scene's frame range (with its step), or the panel's custom range."""
    props = scene.smbs_caustics
    if props.frame_range == 'CUSTOM':
        first, last, step = props.range_start, props.range_end, 1
    else:
        first, last, step = scene.frame_start, scene.frame_end, scene.frame_step
    return list(range(int(first), int(last) + 1, max(int(step), 1)))


class RangeBake:
    """The state of one Bake Frame Range in the interface, driven by the modal operator's events (as
    bake.ModalBake; kept apart from the Operator so that it can be exercised without a window)."""

    what = "Bake Frame Range"

    def __init__(self, report):
        self.report = report
        self.core = self.prep = self.job = self.key = None
        self.frames, self.done, self.i = [], [], 0
        self.pattern, self.frame0, self.last = "", 0, None
        self.cancelled, self.text = False, ""

    def start(self, context) -> bool:
        self.core = load_core(self.report)
        scene = context.scene
        if self.core is None or not free_to_bake(self.report, scene):
            return False
        self.frames = range_frames(scene)
        if not self.frames:
            self.report({'ERROR'}, "The frame range is empty: its end is before its start")
            return False
        self.pattern = frames_pattern(scene.smbs_caustics.output_path.strip() or "//caustics.exr")
        self.key, self.frame0 = scene.name_full, scene.frame_current
        _running[self.key] = self
        context.window_manager.progress_begin(0, 100)
        return self._next(context)

    def _next(self, context) -> bool:
        """Export frame frames[i] and start its bake; False (reported) where that fails."""
        scene = context.scene
        scene.frame_set(self.frames[self.i])
        try:
            self.prep = prepare(context, self.core, frame_pattern=self.pattern)
        except Exception as e:
            report_failure(e, self.core, [], self.report, f"{self.what} (frame {self.frames[self.i]})")
            self._stop(context)
            return False
        self.job = BakeJob(self.core.bake, self.prep.data, self.prep.settings).start()
        return True

    def status(self) -> tuple[float, str]:
        frac, msg = self.job.status() if self.job is not None else (0.0, "")
        n = len(self.frames)
        return (self.i + frac) / n, f"frame {self.frames[min(self.i, n - 1)]} ({self.i + 1}/{n}): {msg}"

    def cancel(self):
        self.cancelled = True
        if self.job is not None:
            self.job.cancel()

    def step(self, context, event_type, event_value="NOTHING") -> set:
        """One event: returns the modal operator's result."""
        if event_type == 'ESC' and event_value == 'PRESS':
            self.cancel()
        if self.cancelled:
            self.job.wait(5.0)  # the core checks between chunks; the frame under way writes nothing
            return self._end(context, 'CANCELLED')
        if event_type != 'TIMER':
            return {'PASS_THROUGH'}
        if not self.job.done:
            fraction, message = self.status()
            context.window_manager.progress_update(100.0 * fraction)
            self.text = f"SMBS Caustics: {100.0 * fraction:.0f}% {message} (Esc to cancel)"
            ModalBake._show(context, self.text)
            return {'PASS_THROUGH'}
        if self.job.error is not None:
            report_failure(self.job.error, self.core, self.prep.warnings, self.report,
                           f"{self.what} (frame {self.frames[self.i]})")
            return self._end(context, 'FAILED')
        if not self._write(self.job.result):
            return self._end(context, 'FAILED')
        self.i += 1
        if self.i == len(self.frames):
            return self._end(context, 'FINISHED')
        if not self._next(context):
            return self._end(context, 'FAILED')
        return {'PASS_THROUGH'}

    def _write(self, result) -> bool:
        """Write the frame just baked; False (reported) where it cannot be written."""
        stats = plain_stats(result)
        why = write_layer(self.prep, result, self.core, stats)
        if why is not None:
            self.report({'ERROR'}, f"{self.what}: frame {self.frames[self.i]} could not be written: {why}")
            return False
        self.done.append(self.frames[self.i])
        self.last = (self.prep, result, stats)
        return True

    def _stop(self, context):
        if _running.get(self.key) is self:
            del _running[self.key]
        context.window_manager.progress_end()
        ModalBake._show(context, None)

    def _end(self, context, how) -> set:
        """The end of the range (how: FINISHED, CANCELLED or FAILED): the frames done as the layer's image
        sequence, the scene back at its frame."""
        self._stop(context)
        scene = bpy.data.scenes.get(self.key)
        if scene is None:
            self.report({'WARNING'}, f"Scene '{self.key}' is gone; the frames were not applied")
            return {'CANCELLED'}
        scene.frame_set(self.frame0)
        if how == 'CANCELLED':
            kept = f"frames {self.done[0]}-{self.done[-1]} kept" if self.done else "no frame was finished"
            self.report({'WARNING'}, f"{self.what} cancelled: {kept}; frame {self.frames[self.i]} was not written")
        if self.done:
            finish_range(scene, self.last, self.pattern, (self.done[0], self.done[-1]), self.core, self.report)
        return {'FINISHED'} if how == 'FINISHED' else {'CANCELLED'}


def finish_range(scene, last, pattern, frames, core, report) -> bool:
    """The frames written as the layer's image sequence in the compositor, the Cycles policy, the reports
    (last: the last frame's prep, result and statistics)."""
    prep, result, stats = last
    layer, per_albedo = result.layer(), result.per_albedo
    stored_pattern = resolve_output_path(pattern)[1]  # as the Image stores it: relative where the Output path is
    stored = core.fill_frame(stored_pattern, frames[0])

    def apply():
        core.apply_sequence(scene, layer, stored_pattern, frames, name=LAYER_NAME, per_albedo=per_albedo,
                            albedo_pattern=albedo_path(stored_pattern) if per_albedo is not None else None)
    done = f"Frames {frames[0]}-{frames[1]} baked in {{:.1f}} s: {stored} ..."
    return conclude(scene, prep, result, core, report, (list(prep.warnings), stats), apply, done)


class SMBS_OT_bake_frame_range(ModalOperator, bpy.types.Operator):
    """Bake the caustic layer of every frame of the range (the scene's or a custom one) as an image
    sequence, which the compositor adds to each frame of the animation"""

    bl_idname = "smbs.bake_frame_range"
    bl_label = "Bake Frame Range"
    bl_options = {'REGISTER', 'UNDO'}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        return run_modal(self, context, RangeBake(self.report))

    def execute(self, context):
        """The frames on this thread (background mode): progress lines, a signal or an error ends the
        range with the frames done kept."""
        rb = RangeBake(self.report)
        rb.core = load_core(self.report)
        if rb.core is None:
            return {'CANCELLED'}
        scene = context.scene
        rb.frames, rb.key, rb.frame0 = range_frames(scene), scene.name_full, scene.frame_current
        rb.pattern = frames_pattern(scene.smbs_caustics.output_path.strip() or "//caustics.exr")
        progress = _Progress(context.window_manager, bpy.app.background)
        how = 'FINISHED'
        for rb.i, f in enumerate(rb.frames):
            scene.frame_set(f)
            rb.prep = None
            try:
                rb.prep = prepare(context, rb.core, frame_pattern=rb.pattern)
                n = len(rb.frames)
                result = rb.core.bake(rb.prep.data, rb.prep.settings,
                                      progress=lambda fr, m: progress((rb.i + fr) / n, f"frame {f} ({rb.i + 1}/{n}): {m}"))
            except Exception as e:  # noqa: BLE001 - reported; the frames done are kept
                report_failure(e, rb.core, rb.prep.warnings if rb.prep else [], self.report, f"{rb.what} (frame {f})")
                how = 'CANCELLED'
                break
            if not rb._write(result):
                how = 'CANCELLED'
                break
        scene.frame_set(rb.frame0)
        if rb.done:
            finish_range(scene, rb.last, rb.pattern, (rb.done[0], rb.done[-1]), rb.core, self.report)
        return {how}


classes = (SMBS_OT_bake_frame_range,)
