"""The albedo of the receivers the camera sees: Cycles' Diffuse Color pass of the scene, which the
add-on's compositor multiplies the layer's per-albedo part by (composite.py), rendered here for the
command line, whose EXR holds the whole caustic in R, G, B (baking.result.complete_layer).

The render is of a copy of the scene (its objects shared, not copied) at its frame, camera,
resolution and pixel filter, with no bounces (the pass is written where camera rays first meet a
surface), ALBEDO_SAMPLES samples per pixel for the texture's detail inside a pixel, no denoising and
no compositing, written to a temporary multilayer EXR; the copy, the file and a Render Result it made
are removed again, the user's scene is not touched.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import bpy
import numpy as np

from ..io.exr import read_passes
from ..trace.camera import CameraModel
from .cycles_passes import plain_passes_render

ALBEDO_SAMPLES = 64  # the pass's samples per pixel: a checker's edges inside a pixel within ~1%


def _render(sc):
    """Cycles' render of scene sc to its render.filepath."""
    bpy.ops.render.render(write_still=True, scene=sc.name)


def diffuse_color(bpy_scene, camera) -> np.ndarray:
    """(H, W, 3) float32, top row first: Cycles' Diffuse Color pass of bpy_scene's first rendered view
    layer, cropped to the render border as the layer is (camera: the exported Scene.Camera). Raises
    RuntimeError where Cycles cannot render it."""
    results = {im.name for im in bpy.data.images if im.type == "RENDER_RESULT"}
    layer = next((vl for vl in bpy_scene.view_layers if vl.use), bpy_scene.view_layers[0]).name
    sc = bpy_scene.copy()
    try:
        with tempfile.TemporaryDirectory() as tmp:
            sc.name = "smbs_albedo"
            sc.frame_set(bpy_scene.frame_current, subframe=bpy_scene.frame_subframe)
            plain_passes_render(sc, Path(tmp) / "albedo.exr", samples=ALBEDO_SAMPLES)
            for vl in sc.view_layers:
                vl.use = vl.name == layer
            sc.view_layers[layer].use_pass_diffuse_color = True
            _render(sc)
            chans = read_passes(sc.render.filepath)
            name = next((n for n in ("Diffuse Color", "DiffCol") if f"{n}.R" in chans), None)
            if name is None:  # Blender 5.0 names the pass in full, 4.x DiffCol
                raise RuntimeError(f"the render has no Diffuse Color pass (it has {', '.join(sorted(chans))})")
            img = np.stack([chans[f"{name}.{c}"] for c in "RGB"], axis=-1)
    finally:
        bpy.data.scenes.remove(sc)
        for im in [im for im in bpy.data.images if im.type == "RENDER_RESULT" and im.name not in results]:
            bpy.data.images.remove(im)
    cam = CameraModel(camera)
    if img.shape[:2] != (cam.H, cam.W):
        raise RuntimeError(f"a render of {img.shape[1]} x {img.shape[0]} pixels, not {cam.W} x {cam.H}")
    if camera.use_border and camera.use_crop_to_border:
        x0, x1, y0, y1 = cam.region
        img = img[y0:y1, x0:x1]
    return np.ascontiguousarray(np.nan_to_num(img, nan=0.0, posinf=0.0, neginf=0.0), np.float32)
