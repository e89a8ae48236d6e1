"""Panels in Properties > Render: the bake, its participants (Cycles' own caustic
flags), advanced solver parameters and the last bake's statistics."""
import json
import textwrap

import bpy

# Statistics keys the panel understands (see smbs_addon.baking.bake), with alternatives.
_SUCCESS_RATE = ("success_rate",)
_WALKS = ("walks_succeeded", "walks_started")
_MUTATIONS_PER_PATH = ("mutations_per_path", "mpp")
_MUTATIONS_PER_SOLUTION = ("mutations_per_success",)  # the paper's mpp: mutations to find one path
_TIME = ("time_s", "time")
_PER_LIGHT = ("lights", "per_light")
_TRIGGERS = (("tir", "TIR"), ("backlit", "back-lit"), ("slow", "slow"))

# Objects that can cast or receive (as exported: anything with triangles), and lights.
_GEOMETRY = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
_TAG = "smbs_caustics"  # custom property on the layer's image (see smbs_addon.blender.composite)


def _number(value):
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _first(stats, keys):
    return next((float(stats[k]) for k in keys if _number(stats.get(k))), None)


def _success_rate(stats):
    rate = _first(stats, _SUCCESS_RATE)
    if rate is None:
        ok, started = (stats.get(k) for k in _WALKS)
        if _number(ok) and _number(started) and started > 0:
            rate = ok / started
    return rate


def _rays(stats):
    """``rays``, or the sum of the ``rays_*`` counters (per light: photon + camera rays)."""
    if _number(stats.get("rays")):
        return float(stats["rays"])
    parts = [v for k, v in stats.items() if k.startswith("rays_") and _number(v)]
    return float(sum(parts)) if parts else None


def _format_count(n):
    for div, suffix in ((1e9, " G"), (1e6, " M"), (1e3, " k")):
        if abs(n) >= div:
            return f"{n / div:.1f}{suffix}"
    return f"{n:.0f}"


def _format_time(seconds):
    if seconds < 60:
        return f"{seconds:.2f} s"
    minutes, sec = divmod(seconds, 60)
    if minutes < 60:
        return f"{minutes:.0f} min {sec:.0f} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours:.0f} h {minutes:.0f} min"


def summarize_stats(stats):
    """Rows of (label, text) for a statistics dict (the whole bake or one light);
    what is not there is left out."""
    rows = []
    if _number(stats.get("walks")):
        rows.append(("Walks", _format_count(stats["walks"])))
    if _number(stats.get("photons")):
        rows.append(("Light Paths", _format_count(stats["photons"])))
    rate = _success_rate(stats)
    if rate is not None:
        rows.append(("Success Rate", f"{100.0 * rate:.1f}%"))
    mpp = _first(stats, _MUTATIONS_PER_PATH)
    if mpp is not None:
        rows.append(("Mutations per Path", f"{mpp:.1f}"))
    mps = _first(stats, _MUTATIONS_PER_SOLUTION)
    if mps is not None:
        rows.append(("Mutations per Solution", f"{mps:.1f}"))
    large = stats.get("large_mutations")
    if isinstance(large, dict) and large:
        known = [(label, large[key]) for key, label in _TRIGGERS if _number(large.get(key))]
        known += [(k, v) for k, v in large.items() if k not in dict(_TRIGGERS) and _number(v)]
        rows.append(("Large Mutations", ", ".join(f"{label} {_format_count(v)}" for label, v in known)))
    trials = stats.get("trials")
    if isinstance(trials, dict) and _number(trials.get("mean")):
        text = f"mean {trials['mean']:.2f}"
        if _number(trials.get("max")):
            text += f", max {trials['max']:.0f}"
        if _number(trials.get("capped")):
            text += f", capped {trials['capped']:.0f}"
            share = trials.get("capped_share_min")
            if trials["capped"] > 0 and _number(share):
                text += f" (at least {100.0 * share:.1f}% of the layer missing)"
        rows.append(("Bernoulli Trials", text))
    handoff = stats.get("handoff")
    if isinstance(handoff, dict) and _number(handoff.get("handoff_paths")):
        rows.append(("Photon Hand-off", f"{_format_count(handoff['handoff_paths'])} paths"))
    eye = stats.get("eye_pass")
    if isinstance(eye, dict):  # paths through normals Cycles' Bump Map Correction bends
        bent = eye.get("bent") if isinstance(eye.get("bent"), dict) else eye  # the eye pass itself: older bakes
        if _number(bent.get("bent_paths")):
            rows.append(("Bent Normals", f"{_format_count(bent['bent_paths'])} paths"))
    rays = _rays(stats)
    if rays is not None:
        rows.append(("Rays", _format_count(rays)))
    seconds = _first(stats, _TIME)
    if seconds is not None:
        rows.append(("Time", _format_time(seconds)))
    if _number(stats.get("compile_s")) and stats["compile_s"] > 0:  # the first bake after installing
        rows.append(("Of Which Compiling", f"{_format_time(stats['compile_s'])} (once)"))
    noise = stats.get("noise")
    if isinstance(noise, dict) and _number(noise.get("relative_noise")) and noise.get("region_pixels"):
        rows.append(("Relative Noise", f"{100.0 * noise['relative_noise']:.1f}%"))
    if _number(stats.get("relative_error")):
        rows.append(("Error", f"\u00b1{100.0 * stats['relative_error']:.1f}% RMS"))
    left_out = stats.get("error_leaves_out")
    if _number(stats.get("relative_error")) and isinstance(left_out, list) and left_out:
        rows.append(("Not in the Error", "; ".join(str(x).split(" (")[0] for x in left_out)))
    if _number(stats.get("seconds_to_halve_error")):
        rows.append(("Half the Error", f"+{_format_time(stats['seconds_to_halve_error'])}"))
    if stats.get("stopped_by") in ("time", "noise"):
        rows.append(("Stopped By", str(stats["stopped_by"]).title()))
    if _number(stats.get("textured_share")):  # coloured by the render's Diffuse Color pass
        rows.append(("On Textures", f"{100.0 * stats['textured_share']:.0f}% × Diffuse Color"))
    return rows


def per_light_stats(stats):
    """[(light name, rows)] from the stats' name -> dict mapping (or list of dicts)."""
    lights = next((stats[k] for k in _PER_LIGHT if isinstance(stats.get(k), (list, dict))), None)
    if lights is None:
        return []
    if isinstance(lights, dict):
        items = list(lights.items())
    else:
        items = [(d.get("name", f"Light {i}"), d) for i, d in enumerate(lights) if isinstance(d, dict)]
    return [(str(name), summarize_stats(d)) for name, d in items if isinstance(d, dict)]


def bake_header(stats):
    """One line naming the bake: method, resolution, batches."""
    parts = []
    if isinstance(stats.get("method"), str):
        parts.append(stats["method"].upper())
    res = stats.get("resolution")
    if isinstance(res, list) and len(res) == 2:
        parts.append(f"{res[0]} x {res[1]}")
    if _number(stats.get("batches_done")):
        parts.append(f"{stats['batches_done']:.0f} batches")
    return ", ".join(parts)


def skipped_stats(stats):
    """Lines for what the bake left out and why."""
    skipped = stats.get("skipped")
    if not isinstance(skipped, list):
        return []
    return [f"{d.get('kind', '')} {d.get('name', '')}: {d.get('reason', '')}".strip()
            for d in skipped if isinstance(d, dict)]


def plan_lines(stats):
    """The bake's plan in words (light -> caster (chain) -> receivers; what was skipped, why)."""
    plan = stats.get("plan")
    words = plan.get("words") if isinstance(plan, dict) else None
    return [str(w) for w in words] if isinstance(words, list) else []


_parsed_cache: dict = {}  # JSON text -> dict: the last bake's statistics and the last comparison


def parse_stats(text):
    """A dict stored as JSON on the scene ({} when empty or unreadable): the last bake's
    statistics, the last comparison. Parsed once per text, not on every redraw."""
    value = _parsed_cache.get(text)
    if value is None:
        try:
            value = json.loads(text) if text else {}
        except ValueError:
            value = {}
        if not isinstance(value, dict):
            value = {}
        if len(_parsed_cache) >= 4:
            _parsed_cache.clear()
        _parsed_cache[text] = value
    return value


def compare_rows(report):
    """Compare Methods' report as (heading, rows of (method, noise, time for the same noise),
    last line): what the panel shows. Empty heading: no comparison."""
    if not isinstance(report, dict):
        return "", [], ""
    if report.get("nothing_to_bake"):
        return "Nothing to compare", [], str(report["nothing_to_bake"])
    rows = report.get("rows")
    if not isinstance(rows, list) or not rows:
        return "", [], ""
    heading = f"{report.get('seconds', 0):g} s each, over {report.get('region_pixels', 0)} caustic pixels"
    out = []
    for r in rows:
        err = r.get("error")
        noise = "no error bar" if not _number(err) else f"\u00b1{100.0 * err:.1f}%" + (
            " (heavy tail)" if r.get("heavy_tail") else "")
        same = r.get("time_for_same_error")
        if _number(same):
            price = f"{same:.2f}x time"
        elif r.get("leaves_out"):
            price = "biased"
        else:
            price = ""
        out.append((str(r.get("method", "?")), noise, price))
    priced = [r for r in rows if _number(r.get("time_for_same_error"))]
    last = ""
    if len(priced) >= 2:
        best = min(priced, key=lambda r: r["time_for_same_error"])
        last = f"Fastest to a given noise: {best['method']}"
    return heading, out, last


def _draw_rows(layout, rows):
    col = layout.column(align=True)
    for label, text in rows:
        split = col.split(factor=0.45)
        split.alignment = 'RIGHT'
        split.label(text=label)
        split.label(text=text)


def _wrap(context, text):
    """Lines of ``text`` that fit the region's width."""
    region = getattr(context, "region", None)
    width = getattr(region, "width", 0) or 400
    scale = getattr(getattr(getattr(context, "preferences", None), "system", None), "ui_scale", 1.0) or 1.0
    chars = max(24, int(width / (6.5 * scale)))
    return textwrap.wrap(text, chars) or [""]


def _draw_text(layout, context, text, icon='NONE'):
    col = layout.column(align=True)
    for i, line in enumerate(_wrap(context, text)):
        col.label(text=line, icon=icon if i == 0 else 'BLANK1')


def _running(scene):
    from ..operators.bake import running_bake

    return running_bake(scene)


def _has_layer_image():
    return any(img.get(_TAG) for img in bpy.data.images)


class _RenderPanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "smbs_caustics")


class SMBS_PT_caustics(_RenderPanel, bpy.types.Panel):
    bl_label = "SMBS Caustics"
    bl_idname = "SMBS_PT_caustics"

    def draw(self, context):
        scene = context.scene
        settings = scene.smbs_caustics
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        col = layout.column()
        col.prop(settings, "method")
        sub = col.column()
        sub.active = settings.method in {"sms", "smbs", "auto"}
        sub.prop(settings, "estimator")
        if settings.estimator == "biased":
            sub.prop(settings, "trials")
        else:
            sub.prop(settings, "max_trials")

        col = layout.column()
        col.prop(settings, "stop_rule")
        rule = getattr(settings, "stop_rule", "SAMPLES")
        sub = col.column()
        sub.active = rule == "SAMPLES"
        sub.prop(settings, "spp")
        sub = col.column()
        sub.active = rule in {"TIME", "NOISE"}
        sub.prop(settings, "time_budget")
        sub = col.column()
        sub.active = rule == "NOISE"
        sub.prop(settings, "noise_target")
        col.prop(settings, "seed")

        col = layout.column()
        col.prop(settings, "use_cycles_flags")
        col.prop(settings, "keep_out_of_cycles")
        col.prop(settings, "output_path")

        bake = _running(scene)
        if bake is not None:
            fraction, message = bake.status()
            row = layout.row(align=True)
            row.progress(factor=fraction, type='BAR', text=f"{100.0 * fraction:.0f}% {message}")
            row.operator("smbs.cancel_bake", text="", icon='CANCEL')
        else:
            row = layout.row(align=True)
            row.scale_y = 1.4
            row.operator("smbs.bake_caustics", icon='RENDER_STILL')
            row.operator("smbs.show_plan", text="", icon='OUTLINER')
            if settings.cycles_kept_out or _has_layer_image():
                row.operator("smbs.remove_caustic_layer", text="", icon='TRASH')
            _draw_frame_range(layout, scene, settings)
        plan_text = getattr(settings, "plan_text", "")
        if plan_text:
            box = layout.box()
            box.label(text="Plan", icon='OUTLINER')
            for line in plan_text.splitlines():
                _draw_text(box, context, line)

        _draw_warnings(layout, context, getattr(settings, "bake_warnings", ""))
        if settings.cycles_note:
            box = layout.box()
            for i, line in enumerate(settings.cycles_note.splitlines()):
                _draw_text(box, context, line, icon='INFO' if i == 0 else 'NONE')
        elif settings.keep_out_of_cycles:
            _draw_text(layout, context, "After a bake that covers every caster, receiver and light, "
                       "Cycles' own caustics are turned off so that nothing is counted twice.", icon='INFO')


def _draw_frame_range(layout, scene, settings):
    """Bake Frame Range and its frames: the scene's range, or Start and End."""
    row = layout.row(align=True)
    row.operator("smbs.bake_frame_range", icon='RENDER_ANIMATION')
    row.prop(settings, "frame_range", text="")
    layout.prop(settings, "seeding")
    if settings.frame_range == 'CUSTOM':
        row = layout.row(align=True)
        row.prop(settings, "range_start")
        row.prop(settings, "range_end")
    else:
        layout.label(text=f"Frames {scene.frame_start}-{scene.frame_end}"
                          + (f", every {scene.frame_step}" if scene.frame_step > 1 else "")
                          + f": {_frames_name(settings.output_path)}")


def _frames_name(path):
    """The frames' file name, as Bake Frame Range writes them (a run of # for the frame)."""
    name = (path.strip() or "//caustics.exr").replace("\\", "/").rsplit("/", 1)[-1] or "caustics.exr"
    if "#" in name:
        return name
    root, dot, ext = name.rpartition(".")
    return f"{root}_####.{ext}" if dot else f"{name}_####.exr"


WARNINGS_SHOWN = 6  # the panel lists this many of the last bake's warnings; the Info editor has them all


def _draw_warnings(layout, context, text):
    """The last bake's warnings (what it could not read or approximated), kept after the bake's reports
    scroll away: the first WARNINGS_SHOWN, then how many more."""
    lines = [line for line in text.splitlines() if line.strip()]
    if not lines:
        return
    box = layout.box()
    box.label(text=f"Last bake: {len(lines)} warning{'s' if len(lines) > 1 else ''}", icon='ERROR')
    for line in lines[:WARNINGS_SHOWN]:
        _draw_text(box, context, line)
    if len(lines) > WARNINGS_SHOWN:
        box.label(text=f"and {len(lines) - WARNINGS_SHOWN} more (Info editor)")


class SMBS_UL_participants(bpy.types.UIList):
    """The scene's objects and lights with Cycles' own caustic flags."""

    bl_idname = "SMBS_UL_participants"

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index=0,
                  flt_flag=0):
        row = layout.row(align=True)
        if item.type == 'LIGHT':
            row.label(text=item.name, icon='LIGHT')
            row.prop(item.data.cycles, "is_caustics_light", text="Light", toggle=True)
        else:
            row.label(text=item.name, icon='OBJECT_DATA')
            row.prop(item.cycles, "is_caustics_caster", text="Cast", toggle=True)
            row.prop(item.cycles, "is_caustics_receiver", text="Receive", toggle=True)

    def filter_items(self, context, data, propname):
        objects = getattr(data, propname)
        shown = self.bitflag_filter_item
        flags = [shown if (ob.type == 'LIGHT' or ob.type in _GEOMETRY) and not ob.hide_render else 0
                 for ob in objects]
        if self.filter_name:
            by_name = bpy.types.UI_UL_list.filter_items_by_name(self.filter_name, shown, objects, "name")
            flags = [f & n for f, n in zip(flags, by_name)]
        order = bpy.types.UI_UL_list.sort_items_by_name(objects, "name") if self.use_filter_sort_alpha else []
        return flags, order


class SMBS_PT_caustics_participants(_RenderPanel, bpy.types.Panel):
    bl_label = "Casters, Receivers and Lights"
    bl_idname = "SMBS_PT_caustics_participants"
    bl_parent_id = "SMBS_PT_caustics"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        scene = context.scene
        settings = scene.smbs_caustics
        layout = self.layout
        if not hasattr(bpy.types.Object, "cycles"):
            layout.label(text="The Cycles add-on is off: there are no caustic flags", icon='ERROR')
            return
        layout.template_list("SMBS_UL_participants", "", scene, "objects", settings,
                             "participant_index", rows=4)
        if scene.world is not None:  # a constant colour or an HDRI lights caustics too (World > Settings)
            row = layout.row(align=True)
            row.label(text=scene.world.name, icon='WORLD')
            row.prop(scene.world.cycles, "is_caustics_light", text="Light", toggle=True)
        mode = settings.use_cycles_flags
        if mode == "OFF":
            text = ("Cycles Flags is Off: the bake takes every specular object, diffuse object and "
                    "light, whatever these flags say (Cycles' own shadow caustics still use them).")
        elif mode == "AUTO":
            text = ("These are Cycles' own flags. A kind (casters, receivers, lights) none of whose "
                    "members is flagged takes part as a whole.")
        else:
            text = "These are Cycles' own flags; only flagged objects and lights take part."
        _draw_text(layout, context, text, icon='INFO')


KERNELS_READY = "Kernels compiled for this machine"
KERNELS_NOT_READY = "Kernels not compiled yet: the first bake adds minutes"


class SMBS_PT_caustics_advanced(_RenderPanel, bpy.types.Panel):
    bl_label = "Advanced"
    bl_idname = "SMBS_PT_caustics_advanced"
    bl_parent_id = "SMBS_PT_caustics"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        settings = context.scene.smbs_caustics
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        col = layout.column()
        col.prop(settings, "batches")
        col.prop(settings, "threads")
        col.prop(settings, "guide")
        col.prop(settings, "sampling")
        col.prop(settings, "world_split")
        col.prop(settings, "indirect")
        col.prop(settings, "radiance")

        col = layout.column(heading="Solver")
        col.active = settings.method != "reference"
        col.prop(settings, "max_iterations")
        sub = col.column()
        sub.active = settings.method != "mnee" and settings.estimator == "unbiased"
        sub.prop(settings, "first_step")
        sub.prop(settings, "stall_stop")
        sub.prop(settings, "anchor")
        col.prop(settings, "solver_threshold")
        col.prop(settings, "uniqueness")
        col.prop(settings, "max_chain")
        col.prop(settings, "clamp_g")
        col.prop(settings, "handoff")
        col.prop(settings, "pilots")

        col = layout.column(heading="Large Mutations")
        col.active = settings.method == "smbs"
        col.prop(settings, "large_mutation_tir")
        col.prop(settings, "large_mutation_backlit")
        col.prop(settings, "large_mutation_slow")
        sub = col.column()
        sub.active = settings.method == "smbs" and settings.large_mutation_slow
        sub.prop(settings, "tau")

        # the kernels compile on their first use after installing or updating (minutes, once)
        from ..operators.kernels import state

        ready = state()
        if ready is not None:
            layout.label(text=KERNELS_READY if ready else KERNELS_NOT_READY, icon='CHECKMARK' if ready else 'INFO')
        layout.operator("smbs.prepare_kernels", icon='SETTINGS')


class SMBS_PT_caustics_statistics(_RenderPanel, bpy.types.Panel):
    bl_label = "Statistics"
    bl_idname = "SMBS_PT_caustics_statistics"
    bl_parent_id = "SMBS_PT_caustics"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        stats = parse_stats(context.scene.smbs_caustics.last_stats)
        if not stats:
            layout.label(text="No bake yet")
            return
        header = bake_header(stats)
        if header:
            layout.label(text=header)
        rows = summarize_stats(stats)
        if rows:
            _draw_rows(layout, rows)
        else:
            layout.label(text="No known statistics in the last bake")
        for name, light_rows in per_light_stats(stats):
            box = layout.box()
            box.label(text=name, icon='LIGHT')
            _draw_rows(box, light_rows)
        plan = plan_lines(stats)
        if plan:
            box = layout.box()
            box.label(text="Plan", icon='OUTLINER')
            for line in plan:
                _draw_text(box, context, line)
        else:
            for line in skipped_stats(stats):
                layout.label(text=line, icon='INFO')


class SMBS_PT_caustics_compare(_RenderPanel, bpy.types.Panel):
    """Compare Methods: each method baked for the same time, their noise side by side."""

    bl_label = "Compare Methods"
    bl_idname = "SMBS_PT_caustics_compare"
    bl_parent_id = "SMBS_PT_caustics"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.smbs_caustics
        row = layout.row(align=True)
        row.prop(settings, "compare_methods", expand=True)
        col = layout.column()
        col.use_property_split = True
        col.use_property_decorate = False
        col.prop(settings, "compare_seconds")
        layout.operator("smbs.compare_methods", icon='SORTTIME')
        heading, rows, last = compare_rows(parse_stats(settings.compare_report))
        if not heading:
            return
        box = layout.box()
        box.label(text=heading, icon='SORTTIME')
        col = box.column(align=True)
        for method, noise, price in [("Method", "Noise", "Time for Same Noise"), *rows]:
            split = col.split(factor=0.3)
            split.label(text=method)
            rest = split.split(factor=0.5)
            rest.label(text=noise)
            rest.label(text=price)
        if last:
            _draw_text(box, context, last, icon='INFO')


classes = (SMBS_PT_caustics, SMBS_UL_participants, SMBS_PT_caustics_participants,
           SMBS_PT_caustics_advanced, SMBS_PT_caustics_compare, SMBS_PT_caustics_statistics)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
