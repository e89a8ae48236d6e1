"""Is a Scene what the render core can bake? Shapes, indices and values, each problem raised as a
SceneError that names the object, material, light or camera it is about (and the scene array only
where no such owner exists, as for a malformed .npz).
"""
from __future__ import annotations

import math

import numpy as np

from ..core.errors import SceneError
from .constants import (CONDUCTOR, DIELECTRIC, DIFFUSE, FRESNEL_CONDUCTOR, FRESNEL_MODELS, LIGHT_TYPES, MATERIAL_KINDS,
                        MAX_BOUNCES, MAX_COLOR, MAX_FILTER_WIDTH, MAX_POWER, MESH, ORTHO, PERSP, RAY_ALL, SENSOR_FITS,
                        flat_axes)

# arrays that must hold finite numbers, by what owns their rows: what a message names
_FINITE_BY_TRIANGLE = ("tri_vertices", "tri_normals", "tri_normals_back", "tri_uvs")
_FINITE_BY_MATERIAL = ("mat_color", "mat_reflect_color", "mat_ior", "mat_roughness", "mat_strength")
_FINITE_BY_LIGHT = ("light_matrix", "light_color", "light_radius", "light_spot_size", "light_spot_blend", "light_size",
                    "light_spread", "light_angle")
_WHAT = {"tri_vertices": "its vertices", "tri_normals": "its normals", "tri_normals_back": "its back normals",
         "tri_uvs": "its UVs", "mat_color": "colour", "mat_reflect_color": "reflection colour", "mat_ior": "IOR",
         "mat_roughness": "roughness", "mat_strength": "strength", "light_matrix": "its transform",
         "light_color": "power", "light_radius": "radius", "light_spot_size": "spot size",
         "light_spot_blend": "spot blend", "light_size": "size", "light_spread": "spread", "light_angle": "angle"}


_TEXT = ("object_names", "mat_names", "light_names", "name", "camera.sensor_fit")
_OWNERS = {"tri_": ("object", "object_names"), "object_": ("object", "object_names"), "mat_": ("material", "mat_names"),
           "light_": ("light", "light_names")}


def _kind_words(v: np.ndarray) -> str:
    kind = v.dtype.kind
    if kind in "US":
        first = v.ravel()[0] if v.size else ""
        return f"text ({str(first)!r})" if v.size else "text"
    return {"c": "complex numbers", "M": "dates", "m": "time spans", "V": "raw bytes", "O": "Python objects"}.get(
        kind, f"values of type {v.dtype}")


def _owner_words(key: str, data: dict) -> str:
    """Who a column of a loaded .npz belongs to, in a message: its first row's owner where the file
    names one (object, material, light), the camera, else the array's own name."""
    if key.startswith("camera."):
        return f"camera {key[7:]}"
    what = _WHAT.get(key, key.split("_", 1)[-1].replace("_", " "))
    for prefix, (noun, names_key) in _OWNERS.items():
        if not key.startswith(prefix):
            continue
        names = data.get(names_key)
        owner = None
        if names is not None and names.dtype.kind in "US" and names.size:
            if prefix == "tri_":
                obj = data.get("tri_object")
                if obj is not None and obj.dtype.kind in "iu" and obj.size and 0 <= int(obj.ravel()[0]) < names.size:
                    owner = str(names.ravel()[int(obj.ravel()[0])])
            else:
                owner = str(names.ravel()[0])
        if owner is not None:
            return f"{noun} '{owner}': {'its ' if not what.startswith('its ') else ''}{what}"
        return f"the {noun}s' {what.removeprefix('its ')}"
    return f"scene array '{key}'"


def check_types(path, data: dict) -> None:
    """The arrays of a loaded .npz (data: name -> array) hold what their fields hold: text for names
    and the camera's sensor fit, numbers for everything else. Raises SceneError naming the object,
    material, light or camera (by the first row's owner), and what the file holds instead."""
    for key, v in data.items():
        v = np.asarray(v)
        if key in _TEXT:
            if v.dtype.kind not in "US":
                what = {"object_names": "object names", "mat_names": "material names", "light_names": "light names",
                        "name": "the scene's name"}.get(key) or _owner_words(key, data)
                raise SceneError(f"{path}: {what} must be text, the file holds {_kind_words(v)}")
        elif v.dtype.kind not in "biuf":
            raise SceneError(f"{path}: {_owner_words(key, data)} must be a number, the file holds {_kind_words(v)}")


def validate(s) -> None:
    """Check the scene s; raise SceneError naming what is wrong."""
    _arrays(s)
    _materials(s)
    _indices_and_finite(s)
    _camera(s)
    _lights(s)
    _world(s)


def _bad_rows(a) -> np.ndarray:
    """The rows (first axis) of a that hold NaN or infinity."""
    a = np.asarray(a, float)
    return np.flatnonzero(~np.isfinite(a.reshape(len(a), -1)).all(axis=1)) if a.size else np.zeros(0, np.int64)


def _finite(s) -> None:
    """No NaN or infinity in the scene's numbers; the message names the object (by its triangles),
    the material or the light that holds one."""
    for name in _FINITE_BY_TRIANGLE:
        bad = _bad_rows(getattr(s, name))
        if bad.size:
            obj = s.object_names[int(s.tri_object[bad[0]])]
            count = f"{bad.size} triangle" + ("s" if bad.size > 1 else "")
            raise SceneError(f"object '{obj}': {_WHAT[name]} hold NaN or infinite values ({count})")
    for name in _FINITE_BY_MATERIAL:
        bad = _bad_rows(getattr(s, name))
        if bad.size:
            raise SceneError(f"material '{s.mat_names[int(bad[0])]}': its {_WHAT[name]} is NaN or infinite")
    for name in _FINITE_BY_LIGHT:
        bad = _bad_rows(getattr(s, name))
        if bad.size:
            raise SceneError(f"light '{s.light_names[int(bad[0])]}': its {_WHAT[name]} is NaN or infinite")
    if not np.all(np.isfinite(s.world_color)):
        raise SceneError("world: its colour is NaN or infinite")


def _arrays(s) -> None:
    """Every array has the shape its counts ask for (or none, where optional)."""
    T = s.n_tris
    expect = {
        "tri_vertices": (T, 3, 3), "tri_normals": (T, 3, 3), "tri_uvs": (T, 3, 2),
        "tri_object": (T,), "tri_material": (T,),
    }
    for name, shape in expect.items():
        a = getattr(s, name)
        if a.shape != shape:
            raise SceneError(f"scene array '{name}' has shape {a.shape}, expected {shape}")
    O, M, L = len(s.object_names), len(s.mat_names), s.n_lights
    if s.tri_normals_back.shape not in ((0, 3, 3), (T, 3, 3)):
        raise SceneError(f"scene array 'tri_normals_back' has shape {s.tri_normals_back.shape}, expected "
                         f"{(T, 3, 3)} or none")
    for name in ("object_caster", "object_receiver", "object_smooth"):
        if getattr(s, name).shape != (O,):
            raise SceneError(f"scene array '{name}' must have one entry per object ({O})")
    for name in ("mat_kind", "mat_ior", "mat_roughness", "mat_strength", "mat_fresnel"):
        if getattr(s, name).shape != (M,):
            raise SceneError(f"scene array '{name}' must have one entry per material ({M})")
    kinds = np.flatnonzero(~np.isin(s.mat_kind, range(len(MATERIAL_KINDS))))
    if kinds.size:
        raise SceneError(f"material '{s.mat_names[int(kinds[0])]}': unknown kind {s.mat_kind[kinds[0]]} (0 to "
                         f"{len(MATERIAL_KINDS) - 1}: {', '.join(MATERIAL_KINDS)})")
    bad = np.flatnonzero(~np.isin(s.mat_fresnel, range(len(FRESNEL_MODELS))))
    if bad.size:
        known = ", ".join(f"{i} ({what})" for i, what in enumerate(FRESNEL_MODELS))
        raise SceneError(f"material '{s.mat_names[int(bad[0])]}': Fresnel model {int(s.mat_fresnel[bad[0]])} "
                         f"is none of {known}")
    if s.mat_bump_correction.shape not in ((0,), (M,)):
        raise SceneError(f"scene array 'mat_bump_correction' must have one entry per material ({M}) or none")
    if s.mat_distribution.shape not in ((0,), (M,)) or not np.isin(s.mat_distribution, (0, 1)).all():
        raise SceneError(f"scene array 'mat_distribution' must have one entry, 0 (GGX) or 1 (Multiscatter GGX), "
                         f"per material ({M}) or none")
    if s.mat_textured.shape not in ((0,), (M,)):
        raise SceneError(f"scene array 'mat_textured' must have one entry per material ({M}) or none")
    wrong = np.flatnonzero(s.mat_textured.astype(bool) & (s.mat_kind != DIFFUSE)) if s.mat_textured.size \
        else []
    if len(wrong):
        raise SceneError(f"material '{s.mat_names[int(wrong[0])]}': only a diffuse material can be textured")
    if s.mat_view_bump.shape not in ((0,), (M,)):
        raise SceneError(f"scene array 'mat_view_bump' must have one entry per material ({M}) or none")
    wrong = np.flatnonzero(s.mat_view_bump.astype(bool) & (s.mat_kind != DIFFUSE)) \
        if s.mat_view_bump.size else []
    if len(wrong):
        raise SceneError(f"material '{s.mat_names[int(wrong[0])]}': only a diffuse material's bumps are "
                         f"read from the view")
    vn, vp = np.asarray(s.view_normals), np.asarray(s.view_points)
    if vn.shape != vp.shape or vn.ndim != 3 or vn.shape[2] != 3:
        raise SceneError(f"scene arrays 'view_normals' {vn.shape} and 'view_points' {vp.shape} must both be "
                         f"(H s, W s, 3)")
    if vn.size and not (np.all(np.isfinite(vn)) and np.all(np.isfinite(vp))):
        raise SceneError("scene arrays 'view_normals' and 'view_points' hold NaN or infinite values")
    for name, n in (("object_visibility", O), ("light_visibility", L)):
        a = getattr(s, name)
        if a.shape not in ((0,), (n,)) or (a.size and not np.all((a >= 0) & (a <= RAY_ALL))):
            raise SceneError(f"scene array '{name}' must have one entry of Ray Visibility bits (0 to "
                             f"{RAY_ALL}) per {name.split('_')[0]} ({n}) or none")
    for name, what in (("light_links", "Light Linking: the objects each light lights"),
                       ("light_blockers", "Shadow Linking: the objects that shadow each light")):
        a = getattr(s, name)
        if a.size and a.shape != (L, O):
            raise SceneError(f"scene array '{name}' must be ({L}, {O}) ({what}) or empty, not {a.shape}")


def _materials(s) -> None:
    """Each material's tables hold values Cycles allows, named by the material."""
    M = len(s.mat_names)
    if s.mat_emission.shape not in ((0, 3), (M, 3)):
        raise SceneError(f"scene array 'mat_emission' must be ({M}, 3) or empty")
    bad = ~np.all(np.isfinite(s.mat_emission) & (s.mat_emission >= 0) & (s.mat_emission <= MAX_POWER),
                  axis=1) if s.mat_emission.size else []
    if np.any(bad):
        raise SceneError(f"material '{s.mat_names[int(np.flatnonzero(bad)[0])]}': emission must be finite, "
                         f"from 0 to {MAX_POWER:g}")
    if s.mat_metal.shape not in ((0, 6), (M, 6)):
        raise SceneError(f"scene array 'mat_metal' must be ({M}, 6) or empty")
    if s.mat_metal.size and not np.all(np.isfinite(s.mat_metal)):
        bad = np.flatnonzero(~np.all(np.isfinite(s.mat_metal), axis=1))
        raise SceneError(f"material '{s.mat_names[int(bad[0])]}': its metal's Fresnel (F82 tint, or index "
                         f"n + ik) is not finite")
    phys = np.flatnonzero(s.mat_fresnel == FRESNEL_CONDUCTOR)
    for m in phys:
        if s.mat_kind[m] != CONDUCTOR:
            raise SceneError(f"material '{s.mat_names[int(m)]}': the physical conductor's Fresnel is a "
                             f"metal's, the material is not one")
        if not s.mat_metal.size or np.any(s.mat_metal[m] < 0) or not np.any(s.mat_metal[m] > 0):
            raise SceneError(f"material '{s.mat_names[int(m)]}': a physical conductor needs its index n and "
                             f"extinction k per channel, not negative (scene array 'mat_metal')")
    if s.mat_metal.size:
        bad = np.flatnonzero((s.mat_kind == DIELECTRIC) & np.any(s.mat_metal[:, :3] < -1.0, axis=1))
        if bad.size:
            raise SceneError(f"material '{s.mat_names[int(bad[0])]}': a glass's Specular Tint must not be "
                             f"negative (scene array 'mat_metal' holds it less 1)")
    if s.mat_film.shape not in ((0, 2), (M, 2)):
        raise SceneError(f"scene array 'mat_film' must be ({M}, 2) or empty")
    bad = ~(np.all(np.isfinite(s.mat_film), axis=1) & (s.mat_film[:, 0] >= 0) & (s.mat_film[:, 0] <= 1e6)
            & (s.mat_film[:, 1] > 0)) if s.mat_film.size else []
    if np.any(bad):
        raise SceneError(f"material '{s.mat_names[int(np.flatnonzero(bad)[0])]}': a thin film needs a thickness "
                         f"from 0 to 1e6 nm and an index above 0")
    if s.mat_absorb.shape not in ((0, 3), (M, 3)):
        raise SceneError(f"scene array 'mat_absorb' must be ({M}, 3) or empty")
    bad = ~np.all(np.isfinite(s.mat_absorb) & (s.mat_absorb >= 0), axis=1) if s.mat_absorb.size else []
    if np.any(bad):
        raise SceneError(f"material '{s.mat_names[int(np.flatnonzero(bad)[0])]}': volume absorption must be "
                         f"finite and not negative")
    wrong = np.flatnonzero((s.mat_absorb.max(axis=1) > 0) & (s.mat_kind != DIELECTRIC)) \
        if s.mat_absorb.size else []
    if len(wrong):
        raise SceneError(f"material '{s.mat_names[int(wrong[0])]}': only glass can absorb light inside it")
    if s.mat_layer.shape not in ((0, 8), (M, 8)):
        raise SceneError(f"scene array 'mat_layer' must be ({M}, 8) or empty")
    fine = np.all(np.isfinite(s.mat_layer) & (s.mat_layer >= 0) & (s.mat_layer <= MAX_COLOR), axis=1)
    if not fine.all():
        raise SceneError(f"material '{s.mat_names[int(np.flatnonzero(~fine)[0])]}': its glossy layer "
                         f"(index, roughness, tint, weight, diffuse roughness, coat weight, coat index, "
                         f"coat roughness) must be finite numbers from 0 to {MAX_COLOR:g}")
    for name in ("mat_color", "mat_reflect_color"):
        if getattr(s, name).shape != (M, 3):
            raise SceneError(f"scene array '{name}' must be ({M}, 3)")


def _indices_and_finite(s) -> None:
    """Triangles point at objects and materials that exist; lights' arrays match their count; no NaN
    or infinity anywhere (named by the object, material or light that holds it)."""
    T, O, M, L = s.n_tris, len(s.object_names), len(s.mat_names), s.n_lights
    if T and (s.tri_object.min() < 0 or s.tri_object.max() >= O):
        raise SceneError("triangle object index out of range")
    if T and (s.tri_material.min() < 0 or s.tri_material.max() >= M):
        raise SceneError("triangle material index out of range")
    for name in ("light_type", "light_radius", "light_soft_falloff", "light_spot_size",
                 "light_spot_blend", "light_shape", "light_spread", "light_angle",
                 "light_caustics"):
        if getattr(s, name).shape != (L,):
            raise SceneError(f"scene array '{name}' must have one entry per light ({L})")
    if s.light_matrix.shape != (L, 4, 4) or s.light_color.shape != (L, 3) \
            or s.light_size.shape != (L, 2):
        raise SceneError("light matrix/colour/size arrays do not match the light count")
    _finite(s)


def _camera(s) -> None:
    """The camera: a finite, non-degenerate matrix and positive lens, sensor, clipping and filter."""
    cam = s.camera
    sides = (cam.resolution_x, cam.resolution_y, cam.resolution_percentage)
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_)) and v >= 1 for v in sides):
        raise SceneError(f"camera resolution {cam.resolution_x} x {cam.resolution_y} at {cam.resolution_percentage}%: "
                         f"each must be a whole number, at least 1")
    if np.shape(cam.matrix_world) != (4, 4) or not np.all(np.isfinite(cam.matrix_world)):
        raise SceneError("camera matrix must be a finite 4x4 matrix")
    for name in ("lens", "sensor_width", "sensor_height", "ortho_scale", "pixel_aspect_x",
                 "pixel_aspect_y", "clip_start", "clip_end", "filter_width"):
        v = getattr(cam, name)
        if not (np.isfinite(v) and v > 0):
            raise SceneError(f"camera {name} must be a positive number, not {v}")
    if not (np.isfinite(cam.shift_x) and np.isfinite(cam.shift_y)):
        raise SceneError("camera shift holds NaN or infinite values")
    if cam.type not in (PERSP, ORTHO):
        raise SceneError(f"camera type {cam.type!r} not supported (perspective or orthographic)")
    if cam.sensor_fit not in SENSOR_FITS:
        raise SceneError(f"camera sensor fit {cam.sensor_fit!r} not supported ({', '.join(SENSOR_FITS)})")
    if cam.filter_width > MAX_FILTER_WIDTH:
        raise SceneError(f"camera filter_width {cam.filter_width:g} pixels: Cycles' pixel filter is at most "
                         f"{MAX_FILTER_WIDTH:g}")
    if flat_axes(np.asarray(cam.matrix_world, float)[:3, :3]):
        raise SceneError("camera: its matrix is degenerate (an axis scaled to zero?), so it has no view direction")
    if cam.use_border:
        b = np.asarray(cam.border, float)
        if b.shape != (4,) or not np.all(np.isfinite(b)) or b.min() < 0 or b.max() > 1:
            raise SceneError(f"camera render border {tuple(np.ravel(b).tolist())}: expected min x, max x, min y, "
                             "max y, each a fraction of the frame from 0 to 1")


def _lights(s) -> None:
    """Lights: known types, power, spread and sizes in range; mesh lights with their triangles."""
    T, L = s.n_tris, s.n_lights
    bad = np.flatnonzero((s.mat_kind == DIELECTRIC) & ~(s.mat_ior > 0))
    if bad.size:
        raise SceneError(f"material '{s.mat_names[bad[0]]}': IOR must be positive")
    if np.shape(s.light_paths) != (4,):
        raise SceneError("scene array 'light_paths' must hold 4 bounce limits (max, diffuse, glossy, transmission)")
    kinds = np.flatnonzero((s.light_type < 0) | (s.light_type >= len(LIGHT_TYPES)))
    if kinds.size:
        raise SceneError(f"light '{s.light_names[kinds[0]]}': unknown type {int(s.light_type[kinds[0]])}")
    if np.any(s.light_color < 0):
        i = int(np.flatnonzero((s.light_color < 0).any(axis=1))[0])
        raise SceneError(f"light '{s.light_names[i]}': negative power")
    if np.any(s.light_color > MAX_POWER):
        i = int(np.flatnonzero((s.light_color > MAX_POWER).any(axis=1))[0])
        raise SceneError(f"light '{s.light_names[i]}': power {s.light_color[i].max():.3g} is beyond "
                         f"{MAX_POWER:g}, more than a float32 caustic layer can hold")
    for name, label in (("mat_color", "colour"), ("mat_reflect_color", "reflection colour")):
        c = getattr(s, name)
        bad = np.flatnonzero(((c < 0) | (c > MAX_COLOR)).any(axis=1)) if len(c) else []
        if len(bad):
            raise SceneError(f"material '{s.mat_names[bad[0]]}': {label} {tuple(c[bad[0]].tolist())} "
                             f"must be between 0 and {MAX_COLOR:g}")
    wide = np.flatnonzero((s.light_spread < 0) | (s.light_spread > math.pi + 1e-6)) if L else []
    if len(wide):
        raise SceneError(f"light '{s.light_names[wide[0]]}': spread {s.light_spread[wide[0]]:g} radians "
                         "must be from 0 to pi (180 degrees)")
    sizes = np.flatnonzero((s.light_size < 0).any(axis=1) | (s.light_radius < 0)
                           | (s.light_angle < 0) | (s.light_spot_size < 0)) if L else []
    if len(sizes):
        raise SceneError(f"light '{s.light_names[sizes[0]]}': negative size, radius, angle or spot size")
    tl = np.asarray(s.tri_light)
    if tl.shape not in ((0,), (T,)) or (tl.size and not np.all((tl >= -1) & (tl < L))):
        raise SceneError(f"scene array 'tri_light' must have one entry per triangle ({T}), a light index or -1, "
                         f"or none")
    owned = np.bincount(tl[tl >= 0], minlength=L) if tl.size else np.zeros(L, np.int64)
    bare = np.flatnonzero((s.light_type == MESH) & (owned == 0))
    if bare.size:
        raise SceneError(f"light '{s.light_names[bare[0]]}': a mesh light without triangles")
    wrong = np.flatnonzero(s.light_type[tl[tl >= 0]] != MESH) if tl.size else []
    if len(wrong):
        raise SceneError(f"light '{s.light_names[int(tl[tl >= 0][wrong[0]])]}': triangles shine as it, but it "
                         f"is not a mesh light")


def _world(s) -> None:
    """The world map and its rotation, and the Light Paths bounce limits."""
    wm = np.asarray(s.world_map)
    if wm.ndim != 3 or wm.shape[2] != 3 or (wm.size and min(wm.shape[:2]) < 1):
        raise SceneError(f"scene array 'world_map' must be (H, W, 3), not {wm.shape}")
    if wm.size and not (np.all(np.isfinite(wm)) and wm.min() >= 0 and wm.max() <= MAX_POWER):
        raise SceneError(f"world map: its pixels must be finite, from 0 to {MAX_POWER:g}")
    R = np.asarray(s.world_map_rotation, float)
    if R.shape != (3, 3) or not (np.all(np.isfinite(R)) and np.allclose(R @ R.T, np.eye(3), atol=1e-6)):
        raise SceneError("scene array 'world_map_rotation' must be a 3 x 3 rotation")
    lp = np.asarray(s.light_paths)
    if not np.all(lp <= MAX_BOUNCES):  # negative: no limit (bounces.Limits.of)
        raise SceneError(f"Light Paths bounces {tuple(lp.tolist())}: each at most {MAX_BOUNCES} "
                         "(Blender's limit)")
