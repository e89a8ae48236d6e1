"""Cycles as the judge: its render settings for a reference of the caustic layer, rendering a .blend
with the bpy module, and reading the EXR files it writes (tools/cycles_reference.py and
tools/conformance.py make the references; tests and benches read them)."""
from __future__ import annotations

import time

import numpy as np


def set_render(scene, spp, seed, caustics, threads, keep_mnee=False):
    """The scene set up for a reference render: Cycles on the CPU, spp samples of seed, caustics on or
    off, no clamping, Filter Glossy, denoising or adaptive sampling, a 32-bit RGB EXR, the Standard view.
    Unless keep_mnee, the objects' caustic caster flags are cleared (not saved): with a caster, a receiver
    and a caustics light present, Cycles turns on MNEE and culls the BSDF-sampled caustic paths it stands
    in for, so e.g. a mirror's caustic is simply missing."""
    scene.render.engine = "CYCLES"
    if not keep_mnee:
        # Cycles turns on MNEE ("shadow caustics") when a caster, a receiver and a caustics
        # light all exist, and then DROPS every path receiver -> caster -> caustics light
        # found by BSDF sampling (it expects MNEE to have handled it). MNEE only solves
        # refraction, so e.g. the mirror's caustic disappears entirely. The reference must be
        # plain path tracing, so clear the caster flags in this in-memory copy (the .blend
        # file is not saved).
        for ob in scene.objects:
            ob.cycles.is_caustics_caster = False
    c = scene.cycles
    c.device = "CPU"
    c.samples = int(spp)
    c.seed = int(seed)
    c.use_animated_seed = False
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = bool(caustics)
    c.caustics_refractive = bool(caustics)
    r = scene.render
    r.threads_mode = "FIXED"
    r.threads = int(threads)
    r.film_transparent = False
    r.use_compositing = False
    r.use_sequencer = False
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    r.image_settings.color_mode = "RGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


def read_exr_rgb(path):
    """An EXR file's first three channels, (H,W,3) float32, top row first."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(str(path))
    if inp is None:
        raise RuntimeError(f"cannot read {path}: {oiio.geterror()}")
    spec = inp.spec()
    img = np.asarray(inp.read_image(oiio.FLOAT), np.float32).reshape(
        spec.height, spec.width, spec.nchannels)
    inp.close()
    return img[:, :, :3]


def render(blend, spp, seed, caustics, threads, path, keep_mnee=False):
    """Render the .blend file blend as set_render sets it up into the EXR file path: the seconds it took."""
    import bpy

    bpy.ops.wm.open_mainfile(filepath=str(blend))
    scene = bpy.context.scene
    set_render(scene, spp, seed, caustics, threads, keep_mnee)
    scene.render.filepath = str(path)
    t = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t
