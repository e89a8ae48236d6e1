"""Panels in Properties > Render: settings, advanced solver parameters, last bake's statistics."""
import json

import bpy

# Statistics keys the panel understands (see smbs_addon.bake), with alternatives.
_SUCCESS_RATE = ("success_rate",)
_WALKS = ("walks_succeeded", "walks_started")
_MUTATIONS_PER_PATH = ("mutations_per_path", "mpp")
_TIME = ("time_s", "time")
_PER_LIGHT = ("lights", "per_light")


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
    """Rows of (label, text) for a statistics dict; what is not there is left out."""
    rows = []
    rate = _success_rate(stats)
    if rate is not None:
        rows.append(("Success Rate", f"{100.0 * rate:.1f}%"))
    mpp = _first(stats, _MUTATIONS_PER_PATH)
    if mpp is not None:
        rows.append(("Mutations per Path", f"{mpp:.1f}"))
    rays = _rays(stats)
    if rays is not None:
        rows.append(("Rays", _format_count(rays)))
    seconds = _first(stats, _TIME)
    if seconds is not None:
        rows.append(("Time", _format_time(seconds)))
    noise = stats.get("noise")
    if isinstance(noise, dict) and _number(noise.get("relative_noise")) and noise.get("region_pixels"):
        rows.append(("Relative Noise", f"{100.0 * noise['relative_noise']:.1f}%"))
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


def skipped_stats(stats):
    """Lines for what the bake left out and why."""
    skipped = stats.get("skipped")
    if not isinstance(skipped, list):
        return []
    return [f"{d.get('kind', '')} {d.get('name', '')}: {d.get('reason', '')}".strip()
            for d in skipped if isinstance(d, dict)]


_parsed_cache = ("", {})


def parse_stats(text):
    """The stats dict stored as JSON on the scene ({} when empty or unreadable)."""
    global _parsed_cache
    if text != _parsed_cache[0]:
        try:
            value = json.loads(text) if text else {}
        except ValueError:
            value = {}
        _parsed_cache = (text, value if isinstance(value, dict) else {})
    return _parsed_cache[1]


def _draw_rows(layout, rows):
    col = layout.column(align=True)
    for label, text in rows:
        split = col.split(factor=0.5)
        split.alignment = 'RIGHT'
        split.label(text=label)
        split.label(text=text)


class SMBS_PT_caustics(bpy.types.Panel):
    bl_label = "SMBS Caustics"
    bl_idname = "SMBS_PT_caustics"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    @classmethod
    def poll(cls, context):
        return context.scene is not None and hasattr(context.scene, "smbs_caustics")

    def draw(self, context):
        settings = context.scene.smbs_caustics
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False

        col = layout.column()
        col.prop(settings, "method")
        sub = col.column()
        sub.active = settings.method in {"sms", "smbs"}
        sub.prop(settings, "estimator")
        sub.prop(settings, "trials")

        col = layout.column()
        col.prop(settings, "spp")
        col.prop(settings, "seed")
        col.prop(settings, "time_budget")
        col.prop(settings, "use_cycles_flags")
        col.prop(settings, "output_path")

        layout.operator("smbs.bake_caustics", icon='RENDER_STILL')


class SMBS_PT_caustics_advanced(bpy.types.Panel):
    bl_label = "Advanced"
    bl_idname = "SMBS_PT_caustics_advanced"
    bl_parent_id = "SMBS_PT_caustics"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        settings = context.scene.smbs_caustics
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.active = settings.method != "reference"

        col = layout.column()
        col.prop(settings, "max_iterations")
        col.prop(settings, "solver_threshold")
        col.prop(settings, "max_chain")

        col = layout.column(heading="Large Mutations")
        col.active = settings.method == "smbs"
        col.prop(settings, "large_mutation_tir")
        col.prop(settings, "large_mutation_backlit")
        col.prop(settings, "large_mutation_slow")
        sub = col.column()
        sub.active = settings.large_mutation_slow
        sub.prop(settings, "tau")


class SMBS_PT_caustics_statistics(bpy.types.Panel):
    bl_label = "Statistics"
    bl_idname = "SMBS_PT_caustics_statistics"
    bl_parent_id = "SMBS_PT_caustics"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        stats = parse_stats(context.scene.smbs_caustics.last_stats)
        if not stats:
            layout.label(text="No bake yet")
            return
        rows = summarize_stats(stats)
        if rows:
            _draw_rows(layout, rows)
        else:
            layout.label(text="No known statistics in the last bake")
        for name, light_rows in per_light_stats(stats):
            box = layout.box()
            box.label(text=name, icon='LIGHT')
            _draw_rows(box, light_rows)
        for line in skipped_stats(stats):
            layout.label(text=line, icon='INFO')


classes = (SMBS_PT_caustics, SMBS_PT_caustics_advanced, SMBS_PT_caustics_statistics)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
