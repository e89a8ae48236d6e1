"""The scene camera -> ``Scene.Camera`` with Cycles' conventions (its render settings, pixel filter
width); a camera that cannot be rendered raises SceneError."""
from __future__ import annotations

import numpy as np

from ..core.errors import SceneError
from ..scene import arrays as S


def orthonormal(m: np.ndarray) -> np.ndarray:
    """The 4x4 matrix with each of its first three columns normalised (scale removed)."""
    out = np.array(m, float)
    for i in range(3):
        n = np.linalg.norm(out[:3, i])
        if n > 0:
            out[:3, i] /= n
    return out


def export_camera(bpy_scene, depsgraph, warn) -> S.Camera:
    cam_ob = bpy_scene.camera
    if cam_ob is None:
        raise SceneError(f"scene '{bpy_scene.name}' has no camera")
    if cam_ob.type != "CAMERA":
        raise SceneError(f"scene camera '{cam_ob.name}' is a {cam_ob.type.lower()} object, not a camera")
    ev = cam_ob.evaluated_get(depsgraph)
    cam = ev.data
    if cam.type == "PANO":
        raise SceneError(f"camera '{cam_ob.name}': panoramic cameras are not supported")
    if cam.type not in ("PERSP", "ORTHO"):
        raise SceneError(f"camera '{cam_ob.name}': {cam.type.lower()} cameras are not supported")
    if cam.dof.use_dof:
        warn(f"camera '{cam_ob.name}': depth of field is ignored")
    r = bpy_scene.render
    cyc = getattr(bpy_scene, "cycles", None)
    fw = float(cyc.filter_width) if cyc is not None and hasattr(cyc, "filter_width") \
        else float(r.filter_size)
    if cyc is not None and getattr(cyc, "pixel_filter_type", "BLACKMAN_HARRIS") != "BLACKMAN_HARRIS":
        warn(f"scene '{bpy_scene.name}': pixel filter {cyc.pixel_filter_type} is treated as "
             f"Blackman-Harris of width {fw:g}")
    return S.Camera(
        matrix_world=orthonormal(np.array(ev.matrix_world)),
        type=S.PERSP if cam.type == "PERSP" else S.ORTHO,
        lens=float(cam.lens), sensor_width=float(cam.sensor_width),
        sensor_height=float(cam.sensor_height), sensor_fit=str(cam.sensor_fit),
        ortho_scale=float(cam.ortho_scale), shift_x=float(cam.shift_x), shift_y=float(cam.shift_y),
        clip_start=float(cam.clip_start), clip_end=float(cam.clip_end),
        resolution_x=int(r.resolution_x), resolution_y=int(r.resolution_y),
        resolution_percentage=int(r.resolution_percentage),
        pixel_aspect_x=float(r.pixel_aspect_x), pixel_aspect_y=float(r.pixel_aspect_y),
        use_border=bool(r.use_border),
        border=(float(r.border_min_x), float(r.border_max_x),
                float(r.border_min_y), float(r.border_max_y)),
        use_crop_to_border=bool(r.use_crop_to_border), filter_width=fw)
