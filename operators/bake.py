"""Bake Caustics: export, bake, write the EXR, composite, keep Cycles from counting twice.

In the interface (``invoke``) the bake runs in a worker thread that touches only
numpy: the scene is exported on the main thread first, a modal timer polls the
job's progress (the window manager's progress and a status text), Esc or the
panel's Cancel button stops it at the core's next check, and the results reach
Blender on the main thread. A cancelled bake changes nothing.

In background mode (``blender -b``, the ``bpy`` module) there is no event loop,
so ``execute()`` runs the same steps synchronously and prints progress lines.
The render core is imported inside the operators so enabling the extension
stays cheap.
"""
from __future__ import annotations

import dataclasses
import inspect
import json
import os
import time
import traceback

import bpy
import numpy as np

from ..ui.properties import BAKE_FIELDS
from . import policy
from .job import BakeJob

LAYER_NAME = "SMBS Caustics"


def _core():
    """The render core's entry points (imported on first use)."""
    from types import SimpleNamespace

    from ..smbs_addon.blender import composite, export, world
    from ..smbs_addon.io import exr as imageio
    from ..smbs_addon.baking import plan
    from ..smbs_addon.io.exr import exr_channels, exr_metadata
    from ..smbs_addon.baking.settings import BakeSettings
    from ..smbs_addon.baking.bake import bake
    from ..smbs_addon.core.errors import BakeCancelled, SceneError
    from ..smbs_addon.io.sequence import fill_frame

    return SimpleNamespace(BakeSettings=BakeSettings, bake=bake, BakeCancelled=BakeCancelled,
                           SceneError=SceneError, export_scene=export.export_scene,
                           apply_layer=composite.apply_layer, remove_layer=composite.remove_layer,
                           diffuse_color_switched_on=composite.diffuse_color_switched_on,
                           has_layer=composite.has_layer, write_exr=imageio.write_exr, write_json=imageio.write_json,
                           exr_writer=imageio.exr_writer, json_writer=imageio.json_writer,
                           save_outputs=imageio.save_outputs,
                           make_plan=plan.make_plan, exr_metadata=exr_metadata, exr_channels=exr_channels,
                           world_unread=world.world_unread, apply_sequence=composite.apply_sequence,
                           layer_sequence=composite.layer_sequence, fill_frame=fill_frame)


def _plain(value):
    """A property value as the core expects it: float32 properties back to the decimal typed."""
    if isinstance(value, float):
        # Blender stores FloatProperty in single precision: 1e-6 comes back as
        # 9.99999997e-07. The shortest decimal that round-trips the float32 is
        # what the user typed (and what the command line passes).
        return float(str(np.float32(value)))
    return value


def bake_settings_from(props, settings_cls):
    """Build ``settings_cls`` from the scene settings named in BAKE_FIELDS.

    Returns (settings, ignored): ``ignored`` lists the settings the core's
    BakeSettings has no field for (a core older or newer than this panel).
    """
    if dataclasses.is_dataclass(settings_cls):
        fields = {f.name for f in dataclasses.fields(settings_cls) if f.init}
    else:
        fields = set(inspect.signature(settings_cls).parameters)
    kwargs = {name: _plain(getattr(props, name)) for name in BAKE_FIELDS if name in fields}
    ignored = [name for name in BAKE_FIELDS if name not in fields]
    rule = getattr(props, "stop_rule", "SAMPLES")
    if rule != "NOISE" and "noise_target" in kwargs:
        kwargs["noise_target"] = 0.0
    if rule == "SAMPLES" and "time_budget" in kwargs:
        kwargs["time_budget"] = 0.0
    if rule in ("TIME", "NOISE") and "spp" in kwargs and "batches" in kwargs:
        kwargs["spp"] = kwargs["batches"]  # a pass of one sample per pixel per batch
    return settings_cls(**kwargs), ignored


def resolve_output_path(raw):
    """(absolute EXR path, path to store on the Image, note or None).

    A path relative to an unsaved blend file goes to the working directory in
    background mode and to Blender's temporary folder otherwise.
    """
    raw = raw.strip() or "//caustics.exr"
    note = None
    if raw.startswith("//") and not bpy.data.filepath:
        base = os.getcwd() if bpy.app.background else bpy.app.tempdir
        path = os.path.join(base, raw[2:])
        note = f"The blend file is not saved; writing the caustic layer to '{os.path.normpath(path)}'"
    else:
        path = bpy.path.abspath(raw)
    if raw.endswith(("/", "\\")) or os.path.isdir(path):
        path = os.path.join(path, "caustics.exr")
    path = os.path.normpath(path)
    if not os.path.splitext(path)[1]:
        path += ".exr"
    # Keep the blend file portable: a relative path stays relative on the Image.
    stored = bpy.path.relpath(path) if raw.startswith("//") and bpy.data.filepath else path
    return path, stored, note


def _json_default(value):
    if hasattr(value, "tolist"):  # numpy scalars and arrays
        return value.tolist()
    if dataclasses.is_dataclass(value):
        return dataclasses.asdict(value)
    return str(value)


class _Progress:
    """The core's ``progress(fraction, message)`` callback for synchronous bakes.

    Prints a line in background mode (at most one per percent or per second,
    plus every new message) and drives the window manager's progress otherwise.
    """

    def __init__(self, window_manager, background):
        self.wm = window_manager
        self.background = background
        self.last = (-1.0, None, 0.0)

    def __call__(self, fraction, message=""):
        self.update(100.0 * min(max(float(fraction), 0.0), 1.0), message)

    def update(self, percent, message=""):
        if not self.background:
            self.wm.progress_update(percent)
            return
        last_percent, last_message, last_time = self.last
        now = time.monotonic()
        if message != last_message or percent - last_percent >= 1.0 or now - last_time >= 1.0:
            print(f"SMBS Caustics: {percent:5.1f}% {message}".rstrip(), flush=True)
            self.last = (percent, message, now)


# ---------------------------------------------------------------------------
# The three steps: prepare (main thread), bake (any thread), finish (main thread)


@dataclasses.dataclass
class Prepared:
    data: object  # smbs_addon Scene
    settings: object  # BakeSettings
    path: str
    stored_path: str
    warnings: list
    blender_lights: list  # (name, is_portal)
    started: float
    world_unread: str | None = None  # the world's name if the export could not read its node setup
    sequence: tuple | None = None  # the layer's frames (stored pattern, first, last): this bake is one of them


def frames_pattern(path: str) -> str:
    """A layer path with a run of # for the frame (Blender's convention): as it is, or _#### before
    its extension."""
    if "#" in os.path.basename(path):
        return path
    root, ext = os.path.splitext(path)
    return f"{root}_####{ext}"


def _output(scene, props, core, frame_pattern):
    """(path, stored path, note, sequence) of a bake's EXR: the Output path; or, for a frame of a range
    (frame_pattern: the range's pattern) or where the layer is a range's image sequence already (a
    frame baked again replaces only that frame), that frame's file of the sequence."""
    seq = core.layer_sequence(LAYER_NAME) if frame_pattern is None else None
    if frame_pattern is None and seq is None:
        return (*resolve_output_path(props.output_path), None)
    note = None
    if frame_pattern is not None:
        path, stored, note = resolve_output_path(frame_pattern)
    else:
        stored = seq[0]
        path = os.path.normpath(bpy.path.abspath(stored))
    f = scene.frame_current
    return core.fill_frame(path, f), core.fill_frame(stored, f), note, seq


def prepare(context, core, output=True, frame_pattern=None) -> Prepared:
    """Export the scene and build the settings (raises SceneError). output False: nothing will
    be written (Compare Methods), so no output path is resolved. frame_pattern: the bake is a frame
    of a range, written to that pattern's file of the current frame."""
    scene = context.scene
    props = scene.smbs_caustics
    warnings = []
    path = stored_path = note = seq = None
    if output:
        path, stored_path, note, seq = _output(scene, props, core, frame_pattern)
    if note:
        warnings.append(note)
    started = time.perf_counter()
    settings, ignored = bake_settings_from(props, core.BakeSettings)
    if ignored:
        print("SMBS Caustics: settings this core does not use:", ", ".join(ignored))
    if frame_pattern is not None or seq is not None:  # a frame of a sequence: its header says which
        settings.frame = int(scene.frame_current)  # (the streams keyed by it with seeding "frame")
    settings.validate()
    data = core.export_scene(scene, context.evaluated_depsgraph_get(), warn=warnings.append)
    lights = [(ob.name, bool(ob.data.type == 'AREA' and getattr(ob.data.cycles, "is_portal", False)))
              for ob in scene.objects if ob.type == 'LIGHT' and not ob.hide_render]
    return Prepared(data, settings, path, stored_path, warnings, lights, started, core.world_unread(scene), seq)


def albedo_path(path):
    """The per-albedo EXR beside a layer's."""
    return os.path.splitext(path)[0] + "_per_albedo.exr" if path else None


def write_layer(prep: Prepared, result, core, stats) -> str | None:
    """Write the EXR (and the per-albedo one, for textured receivers) and the statistics, each read back
    before any replaces the last bake's (io/exr.save_outputs); None, or why they could not be written."""
    layer, per_albedo = result.layer(), result.per_albedo
    try:
        os.makedirs(os.path.dirname(prep.path), exist_ok=True)
        metadata = core.exr_metadata(prep.settings, result)
        outputs = [(prep.path, core.exr_writer(layer, metadata, core.exr_channels(result)))]
        if per_albedo is not None:  # a file of its own beside it, for its Image datablock to read
            outputs.append((albedo_path(prep.path), core.exr_writer(per_albedo, metadata)))
        outputs.append((os.path.splitext(prep.path)[0] + ".json", core.json_writer(stats)))
        core.save_outputs(outputs)
    except (core.SceneError, OSError) as e:
        return str(e)
    return None


def plain_stats(result) -> dict:
    return json.loads(json.dumps(result.stats or {}, default=_json_default))


def finish(scene, prep: Prepared, result, core, report) -> bool:
    """Write the EXR (and the per-albedo one, for textured receivers) and statistics, add the
    layer, apply the Cycles policy.

    ``report(level_set, text)`` as Operator.report. Returns False on failure.
    """
    warnings = list(prep.warnings)
    stats = plain_stats(result)
    why = write_layer(prep, result, core, stats)
    stored_path = prep.stored_path
    if why is not None:
        # The bake is not thrown away: the layer is packed into the blend file instead (and the message
        # says where else the files were kept)
        warnings.append(f"Could not write the caustic layer: {why}; it is packed into the blend file")
        stored_path = None
    seq = prep.sequence if stored_path else None
    layer, per_albedo = result.layer(), result.per_albedo
    if seq is not None:  # a frame of the range's sequence baked again: that frame's file replaced
        f = scene.frame_current
        frames = (min(seq[1], f), max(seq[2], f))

        def apply():
            core.apply_sequence(scene, layer, seq[0], frames, name=LAYER_NAME, per_albedo=per_albedo,
                                albedo_pattern=albedo_path(seq[0]) if per_albedo is not None else None)
    else:
        def apply():
            core.apply_layer(scene, layer, name=LAYER_NAME, filepath=stored_path, per_albedo=per_albedo,
                             per_albedo_filepath=albedo_path(stored_path) if per_albedo is not None else None)
    return conclude(scene, prep, result, core, report, (warnings, stats), apply,
                    f"Caustics baked in {{:.1f}} s: {prep.path if stored_path else 'packed'}")


def conclude(scene, prep: Prepared, result, core, report, said, apply, done) -> bool:
    """Add the layer (apply()), keep the statistics, apply the Cycles policy and report (said: the
    warnings so far and the statistics; done: the last report, {} for the seconds): the end of a bake,
    and of a range of them (its last frame's prep and result)."""
    props = scene.smbs_caustics
    warnings, stats = said
    warnings.extend(str(w) for w in (getattr(result, "warnings", None) or ()))
    had_pass = core.diffuse_color_switched_on(scene)
    try:
        apply()
    except Exception as e:
        traceback.print_exc()
        report({'ERROR'}, f"Could not add the caustic layer to the compositor: {e}")
        return False
    props.last_stats = json.dumps(stats)
    view_layer = core.diffuse_color_switched_on(scene)
    if view_layer and view_layer != had_pass:
        report({'INFO'}, f"Switched on the Diffuse Color pass of view layer '{view_layer}': the caustic on "
                         "textured surfaces is multiplied by their colour in the compositor")

    note_line = -1
    if hasattr(scene, "cycles"):
        try:
            plan = core.make_plan(prep.data, prep.settings.use_cycles_flags)
            noise = (result.stats or {}).get("noise") or {}
            cov = policy.coverage(prep.data, plan, prep.settings.use_cycles_flags, prep.blender_lights,
                                  layer_mean=noise.get("mean"), skipped=(result.stats or {}).get("skipped", ()),
                                  world_unread=prep.world_unread,
                                  nothing=(result.stats or {}).get("nothing_to_bake"))
        except Exception as e:
            traceback.print_exc()
            warnings.append(f"Could not tell which caustics the layer covers ({e}); "
                            "Cycles' own caustics are left as they are")
        else:
            kept_out, lines = policy.update_cycles(scene, props, cov)
            if kept_out:
                print("SMBS Caustics: " + " ".join(lines), flush=True)
            elif cov.nothing:  # the Nothing to bake warning below says it
                note_line = -1
            else:
                warnings.append(" ".join(lines[1:]))
                note_line = len(warnings) - 1  # the panel shows it in the Cycles note already
    if not scene.render.use_compositing:
        warnings.append("Compositing is off (Output Properties > Post Processing); "
                        "renders will not show the caustic layer")

    for message in warnings:
        report({'WARNING'}, message)
    props.bake_warnings = "\n".join(" ".join(m.split()) for i, m in enumerate(warnings) if i != note_line)
    seconds = time.perf_counter() - prep.started
    nothing = result.stats.get("nothing_to_bake")
    if nothing:  # not a failure: the layer is all zero, and the panel's plan says the same
        report({'WARNING'}, f"Nothing to bake: {nothing}; the caustic layer is all zero")
    report({'INFO'}, done.format(seconds))
    return True


def prepare_task(context, core, task, progress=None) -> Prepared:
    """What a task (Compare Methods, Prepare Kernels) runs on: the exported scene and its
    settings as the task takes them, or nothing for a task without the scene (exports False)."""
    if not getattr(task, "exports", True):
        return Prepared(None, None, "", "", [], [], time.perf_counter())
    if progress is not None:
        progress.update(0.0, "exporting the scene")
    prep = prepare(context, core, output=False)
    prep.settings = task.settings(prep.settings)
    return prep


def report_failure(error, core, warnings, report, what="Caustics bake") -> None:
    """An exception from prepare() or the bake, as operator reports."""
    if isinstance(error, core.BakeCancelled):
        report({'WARNING'}, f"{what} cancelled; nothing was changed")
        return
    for message in warnings:
        report({'WARNING'}, message)
    if isinstance(error, core.SceneError):
        report({'ERROR'}, str(error))
    else:
        traceback.print_exception(error)
        report({'ERROR'}, f"Bake failed: {type(error).__name__}: {error}")


# ---------------------------------------------------------------------------
# The bake that runs in the interface


_running: dict = {}  # scene name -> ModalBake, while a bake runs


def running_bake(scene=None):
    """The bake running for ``scene`` (any scene if None), or None."""
    if scene is None:
        return next(iter(_running.values()), None)
    return _running.get(scene.name_full)


def run_modal(op, context, bake):
    """Start bake (a ModalBake or frames.RangeBake) for the modal operator op, whose timer then steps it."""
    op._bake = bake
    if not bake.start(context):
        return {'CANCELLED'}
    wm = context.window_manager
    op._timer = wm.event_timer_add(0.1, window=context.window)
    wm.modal_handler_add(op)
    return {'RUNNING_MODAL'}


def load_core(report):
    """The render core (_core), or None once report (an operator's) has said why it does not load."""
    try:
        return _core()
    except ImportError as e:
        traceback.print_exc()
        report({'ERROR'}, f"SMBS Caustics cannot load its render core: {e}")
        return None


def free_to_bake(report, scene) -> bool:
    """No bake runs for scene; else report says so."""
    if running_bake(scene) is not None:
        report({'ERROR'}, f"A caustics bake is already running for scene '{scene.name}'")
        return False
    return True


class ModalBake:
    """The state of one interactive bake, driven by the modal operator's events.

    Kept apart from the Operator so that it can be exercised without a window. ``task``: what
    runs in the worker and what ends it on the main thread (a bake by default; Compare Methods
    runs ``CompareTask``)."""

    def __init__(self, report, task=None):
        self.report = report
        self.task = task
        self.core = None
        self.prep: Prepared | None = None
        self.job: BakeJob | None = None
        self.key = None
        self.text = ""

    def start(self, context) -> bool:
        self.core = load_core(self.report)
        scene = context.scene
        if self.core is None or not free_to_bake(self.report, scene):
            return False
        try:
            if self.task is None:
                self.prep = prepare(context, self.core)
            else:
                self.prep = prepare_task(context, self.core, self.task)
        except Exception as e:
            report_failure(e, self.core, [], self.report, self.what)
            return False
        self.key = scene.name_full
        run = self.core.bake if self.task is None else self.task.run
        self.job = BakeJob(run, self.prep.data, self.prep.settings).start()
        _running[self.key] = self
        context.window_manager.progress_begin(0, 100)
        return True

    def status(self) -> tuple[float, str]:
        return self.job.status() if self.job is not None else (0.0, "")

    def cancel(self):
        if self.job is not None:
            self.job.cancel()

    def step(self, context, event_type, event_value="NOTHING") -> set:
        """One event: returns the modal operator's result."""
        job = self.job
        if event_type == 'ESC' and event_value == 'PRESS':
            job.cancel()
        if job.cancelled:
            job.wait(1.0)  # the core checks between chunks; the thread is a daemon either way
            self.stop(context)
            self.report({'WARNING'}, f"{self.what} cancelled; nothing was changed")
            return {'CANCELLED'}
        if event_type != 'TIMER':
            return {'PASS_THROUGH'}
        if not job.done:
            fraction, message = job.status()
            context.window_manager.progress_update(100.0 * fraction)
            what = "" if self.task is None else f"{self.what}: "
            self.text = f"SMBS Caustics: {what}{100.0 * fraction:.0f}% {message} (Esc to cancel)"
            self._show(context, self.text)
            return {'PASS_THROUGH'}
        self.stop(context)
        if job.error is not None:
            report_failure(job.error, self.core, self.prep.warnings, self.report, self.what)
            return {'CANCELLED'}
        # Look the scene up again: it may have been deleted, or reloaded by an undo, meanwhile.
        scene = bpy.data.scenes.get(self.key)
        if scene is None or not hasattr(scene, "smbs_caustics"):
            self.report({'WARNING'}, f"Scene '{self.key}' is gone; the bake was not applied")
            return {'CANCELLED'}
        done = finish if self.task is None else self.task.finish
        ok = done(scene, self.prep, job.result, self.core, self.report)
        return {'FINISHED'} if ok else {'CANCELLED'}

    @property
    def what(self) -> str:
        return "Caustics bake" if self.task is None else self.task.what

    def stop(self, context):
        if _running.get(self.key) is self:
            del _running[self.key]
        context.window_manager.progress_end()
        self._show(context, None)

    @staticmethod
    def _show(context, text):
        workspace = getattr(context, "workspace", None)
        if workspace is not None:
            workspace.status_text_set(text)
        screen = getattr(context, "screen", None)
        if screen is not None:
            for area in screen.areas:
                if area.type == 'PROPERTIES':
                    area.tag_redraw()


# ---------------------------------------------------------------------------
# Operators


def _idle(context):
    """A scene with the add-on's settings and no bake running on it."""
    return (context.scene is not None and hasattr(context.scene, "smbs_caustics")
            and running_bake(context.scene) is None)


class ModalOperator:
    """invoke, modal and cancel of an operator that runs a ModalBake in the interface and
    ``execute`` in background mode. ``modal_task(context)``: the ModalBake's task (None: a
    bake), or False to stop before starting (the operator has reported why)."""

    @classmethod
    def poll(cls, context):
        return _idle(context)

    def modal_task(self, context):
        return None

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        task = self.modal_task(context)
        if task is False:
            return {'CANCELLED'}
        return run_modal(self, context, ModalBake(self.report, task))

    def modal(self, context, event):
        result = self._bake.step(context, event.type, event.value)
        if result & {'FINISHED', 'CANCELLED'}:
            context.window_manager.event_timer_remove(self._timer)
        return result

    def cancel(self, context):
        # Blender ends the modal operator (a file is loaded, the window closes).
        self._bake.cancel()
        self._bake.step(context, 'TIMER')
        context.window_manager.event_timer_remove(self._timer)

    def execute_task(self, context, task) -> set:
        """execute() of a task's operator: the task on this thread (background mode, or no
        window), with the same progress lines and reports as a bake."""
        core = load_core(self.report)
        if core is None:
            return {'CANCELLED'}
        background = bpy.app.background
        progress = _Progress(context.window_manager, background)
        if not background:
            context.window_manager.progress_begin(0, 100)
        prep = None
        try:
            prep = prepare_task(context, core, task, progress)
            result = task.run(prep.data, prep.settings, progress=progress)
        except Exception as e:
            report_failure(e, core, prep.warnings if prep else [], self.report, task.what)
            return {'CANCELLED'}
        finally:
            if not background:
                context.window_manager.progress_end()
        task.finish(context.scene, prep, result, core, self.report)
        progress.update(100.0, f"done in {time.perf_counter() - prep.started:.1f} s")
        return {'FINISHED'}


class SMBS_OT_bake_caustics(ModalOperator, bpy.types.Operator):
    """Bake the caustic layer of this scene, write it as an EXR and add it in the compositor"""

    bl_idname = "smbs.bake_caustics"
    bl_label = "Bake Caustics"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        background = bpy.app.background
        core = load_core(self.report)
        if core is None:
            return {'CANCELLED'}
        progress = _Progress(context.window_manager, background)
        if not background:
            context.window_manager.progress_begin(0, 100)
        prep = None
        try:
            progress.update(0.0, "exporting the scene")
            prep = prepare(context, core)
            s = prep.settings
            progress.update(0.0, f"baking ({s.method}, {s.spp} spp, seed {s.seed})")
            result = core.bake(prep.data, s, progress=progress)
        except Exception as e:
            report_failure(e, core, prep.warnings if prep else [], self.report)
            return {'CANCELLED'}
        finally:
            if not background:
                context.window_manager.progress_end()
        progress.update(100.0, f"writing {prep.path}")
        if not finish(context.scene, prep, result, core, self.report):
            return {'CANCELLED'}
        progress.update(100.0, f"done in {time.perf_counter() - prep.started:.1f} s")
        return {'FINISHED'}


class SMBS_OT_cancel_bake(bpy.types.Operator):
    """Stop the caustics bake running for this scene; nothing is changed"""

    bl_idname = "smbs.cancel_bake"
    bl_label = "Cancel Bake"
    bl_options = {'INTERNAL'}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and running_bake(context.scene) is not None

    def execute(self, context):
        running_bake(context.scene).cancel()
        return {'FINISHED'}


class SMBS_OT_remove_caustic_layer(bpy.types.Operator):
    """Take the caustic layer out of the compositor and turn Cycles' own caustics back on
    if a bake turned them off (the EXR file stays)"""

    bl_idname = "smbs.remove_caustic_layer"
    bl_label = "Remove Caustic Layer"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return _idle(context)

    def execute(self, context):
        from ..smbs_addon.blender.composite import remove_layer

        scene = context.scene
        props = scene.smbs_caustics
        remove_layer(scene, name=LAYER_NAME)
        restored = hasattr(scene, "cycles") and policy.restore_cycles(scene, props)
        props.cycles_note = ""
        props.bake_warnings = ""
        self.report({'INFO'}, "Caustic layer removed" + (
            "; Cycles' own caustics are back as they were" if restored else ""))
        return {'FINISHED'}


class SMBS_OT_show_plan(bpy.types.Operator):
    """Show what a bake would trace, before baking: per light the casters whose caustic the
    camera can see, by which chains, onto which receivers; what is skipped and why"""

    bl_idname = "smbs.show_plan"
    bl_label = "Show Plan"
    bl_options = {'REGISTER'}

    @classmethod
    def poll(cls, context):
        return _idle(context)

    def execute(self, context):
        from ..smbs_addon.baking.bake import plan_words

        scene = context.scene
        props = scene.smbs_caustics
        core = _core()
        try:
            settings, _ = bake_settings_from(props, core.BakeSettings)
            settings.validate()
            data = core.export_scene(scene, context.evaluated_depsgraph_get(), warn=lambda m: None)
            lines = plan_words(data, settings)
        except core.SceneError as e:
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        props.plan_text = "\n".join(lines)
        for line in lines:
            self.report({'INFO'}, line)
        return {'FINISHED'}


classes = (SMBS_OT_bake_caustics, SMBS_OT_cancel_bake, SMBS_OT_remove_caustic_layer, SMBS_OT_show_plan)


def cancel_all(timeout=2.0):
    """Stop every running bake (unregister): the worker threads end at their next check."""
    for bake in list(_running.values()):
        bake.cancel()
        if bake.job is not None:
            bake.job.wait(timeout)
    _running.clear()
