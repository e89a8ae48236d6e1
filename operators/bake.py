"""The Bake Caustics operator: export, bake, write the EXR, composite.

``execute()`` runs synchronously, which is what headless use needs (no window,
no timers). The render core is imported inside ``execute()`` so that enabling
the extension stays cheap.
"""
import dataclasses
import inspect
import json
import os
import time
import traceback

import bpy

# Scene settings that are not bake settings.
_NOT_BAKE_SETTINGS = {"output_path", "last_stats", "name"}


def bake_settings_from(props, settings_cls):
    """Build ``settings_cls`` from the scene settings, matching names.

    Returns (settings, ignored): ``ignored`` lists the scene settings the core's
    BakeSettings has no field for.
    """
    if dataclasses.is_dataclass(settings_cls):
        fields = {f.name for f in dataclasses.fields(settings_cls) if f.init}
    else:
        fields = set(inspect.signature(settings_cls).parameters)
    kwargs, ignored = {}, []
    for prop in props.bl_rna.properties:
        name = prop.identifier
        if name in _NOT_BAKE_SETTINGS or prop.type == 'POINTER':
            continue
        if name in fields:
            kwargs[name] = getattr(props, name)
        else:
            ignored.append(name)
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
    """The core's ``progress(fraction, message)`` callback.

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


class SMBS_OT_bake_caustics(bpy.types.Operator):
    """Bake the caustic layer of this scene, write it as an EXR and add it in the compositor"""

    bl_idname = "smbs.bake_caustics"
    bl_label = "Bake Caustics"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "smbs_caustics")

    def execute(self, context):
        scene = context.scene
        props = scene.smbs_caustics
        background = bpy.app.background
        try:
            from ..smbs_addon.bake import BakeSettings, bake
            from ..smbs_addon.composite import apply_layer
            from ..smbs_addon.errors import BakeCancelled, SceneError
            from ..smbs_addon.export import export_scene
            from ..smbs_addon.imageio import write_exr
        except ImportError as e:
            traceback.print_exc()
            self.report({'ERROR'}, f"SMBS Caustics cannot load its render core: {e}")
            return {'CANCELLED'}

        warnings = []
        warn = warnings.append
        path, stored_path, note = resolve_output_path(props.output_path)
        if note:
            warn(note)
        progress = _Progress(context.window_manager, background)
        started = time.perf_counter()
        if not background:
            context.window_manager.progress_begin(0, 100)
        try:
            progress.update(0.0, "exporting the scene")
            data = export_scene(scene, context.evaluated_depsgraph_get(), warn=warn)
            settings, ignored = bake_settings_from(props, BakeSettings)
            if ignored:
                print("SMBS Caustics: settings this core does not use:", ", ".join(ignored))
            progress.update(0.0, f"baking ({props.method}, {props.spp} spp)")
            result = bake(data, settings, progress=progress)
        except SceneError as e:
            for message in warnings:
                self.report({'WARNING'}, message)
            self.report({'ERROR'}, str(e))
            return {'CANCELLED'}
        except BakeCancelled as e:
            self.report({'WARNING'}, str(e) or "Bake cancelled")
            return {'CANCELLED'}
        except Exception as e:
            traceback.print_exc()
            self.report({'ERROR'}, f"Bake failed: {type(e).__name__}: {e}")
            return {'CANCELLED'}
        finally:
            if not background:
                context.window_manager.progress_end()

        warnings.extend(str(w) for w in (getattr(result, "warnings", None) or ()))
        stats = json.loads(json.dumps(result.stats or {}, default=_json_default))
        props.last_stats = json.dumps(stats)

        metadata = {"method": props.method, "estimator": props.estimator,
                    "spp": props.spp, "seed": props.seed, "stats": stats}
        try:
            progress.update(100.0, f"writing {path}")
            os.makedirs(os.path.dirname(path), exist_ok=True)
            write_exr(path, result.image, metadata)
        except (SceneError, OSError) as e:
            # The bake is not thrown away: the layer is packed into the blend file instead.
            warn(f"Could not write '{path}' ({e}); the caustic layer is packed into the blend file")
            stored_path = None
        try:
            apply_layer(scene, result.image, filepath=stored_path)
        except Exception as e:
            traceback.print_exc()
            self.report({'ERROR'}, f"Could not add the caustic layer to the compositor: {e}")
            return {'CANCELLED'}
        if not scene.render.use_compositing:
            warn("Compositing is off (Output Properties > Post Processing); "
                 "renders will not show the caustic layer")

        for message in warnings:
            self.report({'WARNING'}, message)
        seconds = time.perf_counter() - started
        progress.update(100.0, f"done in {seconds:.1f} s")
        self.report({'INFO'}, f"Caustics baked in {seconds:.1f} s: {path if stored_path else 'packed'}")
        return {'FINISHED'}


classes = (SMBS_OT_bake_caustics,)
