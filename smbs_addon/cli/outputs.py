"""What the command line writes for a bake: the EXR (the whole caustic in R, G, B, its std, the
per-albedo channels, the header a second run and a merge read) and the statistics JSON beside it."""
from __future__ import annotations

import json

from ..baking.result import complete_layer
from ..core.version import code_version
from ..io.exr import exr_channels, exr_metadata, exr_writer, json_writer, samples_done


def albedo_for(inp, scene, result, warn):
    """Cycles' Diffuse Color pass where the layer has a caustic on textured receivers seen directly
    (None otherwise, or where there is no Cycles to render it: an .npz input, which warn says)."""
    if result.per_albedo is None or not result.per_albedo.any():
        return None
    try:
        albedo = inp.albedo(scene.camera)
    except RuntimeError as e:
        albedo, why = None, f"Cycles could not render the Diffuse Color pass ({e})"
    else:
        why = "an .npz scene carries no albedo (bake the .blend)"
    if albedo is None:
        warn(f"the caustic on textured receivers is in the EXR's per_albedo_R, _G, _B only, to multiply by the "
             f"render's Diffuse Color pass: {why}")
    return albedo


def bake_outputs(settings, result, out, stats_path, albedo=None, scene_digest=None):
    """([(path, writer)] for io.exr.save_outputs, the R, G, B written, their std): the layer made whole
    with albedo (baking.result.complete_layer) where there is one."""
    rgb, std = complete_layer(result, albedo)
    stats = result.stats
    stats.update(samples=samples_done(settings, stats), code=code_version())
    if result.per_albedo is not None:
        stats["rgb"] = "complete" if albedo is not None else "without the caustic on textured receivers"
    if scene_digest:
        stats["scene_digest"] = scene_digest
    meta = exr_metadata(settings, result, scene_digest, complete=albedo is not None)
    outputs = [(out, exr_writer(rgb, meta, exr_channels(result, std))), (stats_path, json_writer(stats))]
    return outputs, rgb, std


def header_says_same(meta: dict, settings, scene_digest: str, code: str) -> str | None:
    """None where an EXR's header says it holds this bake (the same code, settings and scene: the same
    pixels), else what differs, in words."""
    if not meta:
        return "it is not a caustic layer this code can read"
    for key, want, what in (("code", code, "code"), ("settings_key", settings.image_key(), "settings"),
                            ("scene", scene_digest, "scene")):
        if str(meta.get(key, "")) != str(want):
            return f"other {what}"
    return None


def stats_of(meta: dict) -> dict:
    try:
        return json.loads(meta.get("stats", "{}"))
    except (TypeError, ValueError):
        return {}
