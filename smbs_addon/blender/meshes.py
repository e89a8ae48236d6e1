"""Meshes: an evaluated object's triangles (``mesh_arrays``, via to_mesh(), freed again) with their
corner normals, UVs and builder materials (``read_mesh``), the bumps of their mirrors and glass cut
finer and baked by Cycles (``bake_bumps``: bump.py, cycles_passes.bake_normals), and each instance in
world space (``to_world``)."""
from __future__ import annotations

import numpy as np

from ..scene import bump
from .cycles_passes import bake_normals

MESH_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}


def mesh_arrays(ob_eval):
    """Local-space triangle arrays of an evaluated object, or None if it has no triangles."""
    me = ob_eval.to_mesh()
    if me is None:
        return None
    try:
        me.calc_loop_triangles()
        T = len(me.loop_triangles)
        if T == 0:
            return None
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        tv = np.empty(T * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tv)
        tl = np.empty(T * 3, np.int32)
        me.loop_triangles.foreach_get("loops", tl)
        mi = np.empty(T, np.int32)
        me.loop_triangles.foreach_get("material_index", mi)
        sm = np.empty(T, bool)
        me.loop_triangles.foreach_get("use_smooth", sm)
        cn = np.empty(len(me.loops) * 3, np.float32)
        me.corner_normals.foreach_get("vector", cn)
        uv = None
        layer = me.uv_layers.active
        if layer is not None and len(me.loops):
            uvs = np.empty(len(me.loops) * 2, np.float32)
            if hasattr(layer, "uv"):
                layer.uv.foreach_get("vector", uvs)
            else:
                layer.data.foreach_get("uv", uvs)
            uv = uvs.reshape(-1, 2)[tl].reshape(T, 3, 2).astype(float)
        mats = list(me.materials)
    finally:
        ob_eval.to_mesh_clear()
    co = co.reshape(-1, 3).astype(float)
    return dict(
        verts=co[tv].reshape(T, 3, 3), co=co, tv=tv.reshape(T, 3),
        normals=cn.reshape(-1, 3).astype(float)[tl].reshape(T, 3, 3),
        uvs=uv, uv_name=None if layer is None else layer.name, mat_index=mi, smooth=sm, mesh_materials=mats)


def read_mesh(ob, M, materials, warn, check_levels) -> dict | None:
    """An evaluated mesh object's local arrays (mesh_arrays) with its builder material per triangle
    (tri_material, from materials: a MaterialTable) and, where a bumped mirror or glass is among
    them, what baking its bumps needs (bump_source: bake_bumps); None if it has no triangles.
    check_levels: warn where a modifier's viewport level is not its render level (a viewport
    depsgraph exports the former)."""
    orig = ob.original
    if check_levels:
        for mod in orig.modifiers:
            lv, rl = getattr(mod, "levels", None), getattr(mod, "render_levels", None)
            if mod.show_viewport and lv is not None and rl is not None and lv != rl:
                warn(f"object '{orig.name}': modifier '{mod.name}' is exported at its "
                     f"viewport level {lv}, not its render level {rl}")
    local = mesh_arrays(ob)
    if local is None:
        return None
    slots = [s.material for s in ob.material_slots] or local["mesh_materials"]
    # no slots: default diffuse; an empty slot: default diffuse; an index past
    # the last slot uses the last slot (as Blender does)
    ids = np.array([materials.id_of(m) for m in slots] or [materials.id_of(None)], np.int32)
    local["mat_index"] = np.clip(local["mat_index"], 0, len(ids) - 1)
    tri_mat = ids[local["mat_index"]]
    local["tri_material"] = tri_mat.astype(np.int32)
    bump_specs = materials.bump_specs
    if any(int(m) in bump_specs for m in np.unique(tri_mat)):
        local["bump_source"] = dict(
            name=orig.name, matrix=M, texspace=(tuple(ob.data.texspace_location),
                                                tuple(ob.data.texspace_size)),
            slots=[bump_specs.get(int(m)) for m in ids])
    return local


def bake_bumps(mesh_cache, bump_specs, warn):
    """Bake the bumps of every mesh in mesh_cache (key -> read_mesh's arrays) with a bump_source, in
    place: triangle budgets shared by their areas (bump.targets), each cut and baked by _bumped.
    (Run once the depsgraph's instances are read: the bake adds a scene of its own.)"""
    bumped = [key for key, local in mesh_cache.items() if local is not None and "bump_source" in local]
    areas = [_area(mesh_cache[key]["verts"], mesh_cache[key]["bump_source"]["matrix"]) for key in bumped]
    for key, target in zip(bumped, bump.targets(areas)):
        local = mesh_cache[key]
        source = local.pop("bump_source")
        specs = {int(m): bump_specs[int(m)] for m in np.unique(local["tri_material"]) if int(m) in bump_specs}
        mesh_cache[key] = _bumped(local, specs, source, int(target), warn)


def to_world(local, M):
    """World-space (verts, normals, uvs, normals from behind or None: bump.bend) for one instance,
    fixing winding for negative scale."""
    A, t = M[:3, :3], M[:3, 3]
    v = local["verts"] @ A.T + t
    try:
        nt = np.linalg.inv(A).T
    except np.linalg.LinAlgError:
        nt = A
    n = local["normals"] @ nt.T
    uv = local["uvs"]
    if np.linalg.det(A) < 0:  # mirrored: keep the winding (geometric normal) on the normal's side
        v = v[:, [0, 2, 1]]
        n = n[:, [0, 2, 1]]
        uv = None if uv is None else uv[:, [0, 2, 1]]
    fn = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    fl = np.linalg.norm(fn, axis=1, keepdims=True)
    fn = np.divide(fn, fl, out=np.zeros_like(fn), where=fl > 0)
    flat = ~local["smooth"]
    n[flat] = fn[flat][:, None, :]
    nl = np.linalg.norm(n, axis=2, keepdims=True)
    bad = ~(nl[..., 0] > 0)
    n = np.divide(n, nl, out=np.zeros_like(n), where=nl > 0)
    if bad.any():  # degenerate normals: fall back to the face normal
        n[bad] = np.broadcast_to(fn[:, None, :], n.shape)[bad]
    b = local.get("bump")
    if b is None:
        return v, n, uv, None
    # Cycles' Bump node, in world space, from the front and from behind (bump.py)
    tv = local["tv"] if np.linalg.det(A) >= 0 else local["tv"][:, [0, 2, 1]]
    n, back = bump.bend(v, n, tv, b["heights"], b["distance"], b["strength"])
    if b["flips"].all():
        return v, n, uv, None
    return v, n, uv, np.where(b["flips"][:, None, None], n, back)


def _area(verts, M) -> float:
    """The world surface area of local triangles (T, 3, 3) under matrix M."""
    v = verts @ np.asarray(M, float)[:3, :3].T
    return float(0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum())


def _bumped(local, specs, source, target, warn):
    """A mesh's arrays with its bumped mirrors and glass (specs: builder material id -> bump_of's
    (kind, node name, Distance, Strength, flips) and the Material) cut into about `target` triangles,
    Cycles' values baked at every vertex (bump.py): a Bump node's Height (the normals bent in to_world,
    in world space, from the front and, where the bump does not flip, from behind), any other driven
    Normal as it is (the corner normals replaced). The arrays unchanged, and said so, where Cycles
    cannot bake them. (A vertex between a bumped material and another takes Cycles' Height there as
    its point-domain bake gives it.)"""
    tri_mat = local["tri_material"]
    kind = np.zeros(len(tri_mat), np.int64)  # 0: as it is, 1: a Bump's Height, 2: a Normal's vector
    dist, strength = np.zeros(len(tri_mat)), np.zeros(len(tri_mat))
    flips = np.ones(len(tri_mat), bool)
    for m, spec in specs.items():
        on = tri_mat == m
        kind[on] = 1 if spec[0] == "height" else 2
        dist[on], strength[on], flips[on] = spec[2], spec[3], spec[4]
    n = bump.segments(len(tri_mat), target)
    co, tv, normals, uvs, parent = bump.subdivide(local["tv"], local["co"], local["normals"], local["uvs"], n)
    slot, kind = local["mat_index"][parent], kind[parent]
    out = dict(local, co=co, tv=tv, verts=co[tv], normals=normals, uvs=uvs, mat_index=slot,
               smooth=np.ones(len(tv), bool), tri_material=tri_mat[parent])
    try:
        if (kind == 1).any():
            heights = bake_normals(source, co, tv, slot, uvs, local["uv_name"], "height")
            if not np.all(np.isfinite(heights)):
                warn(f"object '{source['name']}': its Bump node's Height is not finite everywhere; taken as 0 there")
                heights = np.nan_to_num(heights, nan=0.0, posinf=0.0, neginf=0.0)
            out["bump"] = dict(heights=heights, distance=dist[parent], flips=flips[parent],
                               strength=np.where(kind == 1, strength[parent], 0.0))
        if (kind == 2).any():
            world = bake_normals(source, co, tv, slot, uvs, local["uv_name"], "vector")
            # to the object's space, where to_world takes every instance's normals from
            A = np.asarray(source["matrix"], float)[:3, :3]
            nl = world @ A
            ln = np.linalg.norm(nl, axis=-1, keepdims=True)
            good = (kind == 2)[:, None] & np.isfinite(ln[..., 0]) & (ln[..., 0] > 1e-12)
            out["normals"] = np.where(good[..., None], nl / np.where(good[..., None], ln, 1.0), normals)
    except Exception as e:  # Cycles could not bake: the surface as it is, and said so
        warn(f"object '{source['name']}': the bumps of its Normal could not be baked ({e}); its caustic is "
             f"baked from the unbumped surface")
        return local
    return out
