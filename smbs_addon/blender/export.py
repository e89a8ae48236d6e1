"""Blender scene -> smbs ``Scene`` (numpy arrays): ``export_scene``, the one entry point of the
export, which the add-on's operators and the command line (open_blend.py) call.

``export_scene(bpy_scene)`` walks the evaluated depsgraph (so modifiers, geometry
nodes and instances are included), converts every renderable mesh to world-space
triangles with per-corner shading normals (meshes.py), classifies materials from their node
trees (materials.py, bsdfs.py), converts lights (lights.py), the camera (camera.py) and the
world (world.py) with Cycles' conventions, reads Light and Shadow Linking (visibility.py),
asks Cycles for the bakes and renders bumps need (cycles_passes.py), and returns a
validated ``Scene``. The user's scene is only read: temporary meshes from
``to_mesh()`` are freed with ``to_mesh_clear()``.

Anything that cannot be represented is reported through ``warn`` (a callable
taking one string; by default the messages go to ``logging``) and replaced by a
stated fallback, e.g. an unsupported material becomes diffuse with albedo 0.8.
"""
from __future__ import annotations

import logging
import os

import bpy
import numpy as np

from ..core.errors import SceneError
from ..scene import arrays as S
from ..scene.builder import SceneBuilder
from .camera import export_camera
from .cycles_passes import view_maps
from .lights import export_light
from .materials import MaterialTable
from .meshes import MESH_TYPES, bake_bumps, read_mesh, to_world
from .visibility import LinkedNames, ray_visibility, say_visibility
from .world import add_world

log = logging.getLogger(__name__)


def missing_libraries(bpy_scene=None) -> list:
    """[(library file as stored, absolute path, [names of the scene's objects whose data it held])]
    for each linked library whose file is not there: Blender opens the .blend with empty placeholders
    for what it linked (ID.is_missing), which bake as nothing."""
    out = []
    for lib in bpy.data.libraries:
        path = bpy.path.abspath(lib.filepath, library=lib.library)
        if os.path.exists(path) and not getattr(lib, "is_missing", False):
            continue
        names = []
        if bpy_scene is not None:
            for ob in bpy_scene.objects:
                ids = [ob, ob.data, ob.instance_collection]
                if any(i is not None and (i.library == lib or getattr(i, "is_missing", False)) for i in ids):
                    names.append(ob.name)
        out.append((lib.filepath, path, names))
    return out


def say_missing_libraries(bpy_scene, warn) -> None:
    """A warning per linked library that is missing, naming the objects it left empty."""
    for stored, path, names in missing_libraries(bpy_scene):
        what = (f": {', '.join(repr(n) for n in names[:6])}{' and more' if len(names) > 6 else ''} "
                f"{'is an empty placeholder and bakes' if len(names) == 1 else 'are empty placeholders and bake'} as nothing"
                if names else "; what it linked is missing from the scene")
        warn(f"linked library '{stored}' is missing (no file at {path}){what}")


def _default_depsgraph(bpy_scene):
    ctx = bpy.context
    if ctx.scene == bpy_scene:
        return ctx.evaluated_depsgraph_get()
    vl = bpy_scene.view_layers[0]
    dg = vl.depsgraph
    if dg is None:  # a scene no window shows (or one linked from a library): evaluate it here
        with ctx.temp_override(scene=bpy_scene, view_layer=vl):
            return ctx.evaluated_depsgraph_get()
    dg.update()
    return dg


def _instances(depsgraph):
    """The depsgraph's renderable mesh and light instances, in order: (instance, its name, how many
    before it took that name, world matrix). An instance's name is its instancer's and its own; a
    name met again gets a suffix .1, .2, ..."""
    names_used = {}
    for inst in depsgraph.object_instances:
        ob = inst.object
        orig = ob.original
        if inst.is_instance:
            parent = inst.parent
            if parent is not None and parent.original.hide_render:
                continue
        elif not inst.show_self:
            continue
        if orig.hide_render:
            continue
        if ob.type not in MESH_TYPES and ob.type != "LIGHT":
            continue
        M = np.array(inst.matrix_world, float)
        name = orig.name
        if inst.is_instance and inst.parent is not None:
            name = f"{inst.parent.original.name}/{name}"
        k = names_used.get(name, 0)
        names_used[name] = k + 1
        if k:
            name = f"{name}.{k}"
        yield inst, name, k, M


def _read_instances(b, depsgraph, materials, warn):
    """Every instance of the depsgraph: lights into SceneBuilder b, meshes read once per object and
    data (materials: a MaterialTable). Returns (meshes: (name, mesh_cache key, matrix, caster,
    receiver, Ray Visibility, original object) in order; emitters: (the builder's light entry, its
    original object), their Light Linking read once every mesh is known; mesh_cache: key -> read_mesh's
    arrays or None; view_objects: each mesh's object (or its instancer), in order, by its key: what
    the view may hold)."""
    mesh_cache, meshes, emitters, view_objects = {}, [], [], {}
    viewport = getattr(depsgraph, "mode", "VIEWPORT") == "VIEWPORT"
    for inst, name, k, M in _instances(depsgraph):
        ob = inst.object
        orig = ob.original
        if ob.type == "LIGHT":
            n_lights = len(b.lights)
            export_light(b, name, ob, M, warn)
            if len(b.lights) > n_lights:
                emitters.append((b.lights[-1], orig))
            continue
        key = (orig.name_full, ob.data.as_pointer() if ob.data is not None else 0)
        if key not in mesh_cache:
            mesh_cache[key] = read_mesh(ob, M, materials, warn, viewport and not inst.is_instance)
        if mesh_cache[key] is None:
            continue
        if k == 0 and not inst.is_instance:
            say_visibility(orig, warn)
        instancer = inst.parent.original if inst.is_instance and inst.parent is not None else None
        view_objects.setdefault(key, {})[orig if instancer is None else instancer] = None
        visibility = ray_visibility(orig)
        if instancer is not None:  # Cycles: an instance inherits what its instancer hides
            visibility &= ray_visibility(instancer)
        meshes.append((name, key, M, bool(orig.cycles.is_caustics_caster), bool(orig.cycles.is_caustics_receiver),
                       visibility, orig))
    return meshes, emitters, mesh_cache, view_objects


def _add_meshes(b, meshes, mesh_cache, view_objects, linked) -> dict:
    """Each mesh instance into SceneBuilder b in world space, with the objects it is lit by and
    shadowed from (linked: visibility.LinkedNames). Returns the objects with a bumped diffuse (a
    receiver, by the plan's rules), in order: the view of them is rendered alone (view_maps)."""
    view_bumped = {}
    for name, key, M, caster, receiver, visibility, orig in meshes:
        local = mesh_cache[key]
        v, n, uv, back = to_world(local, M)
        b.mesh_corners(name, v, n, uv, local["tri_material"], caster=caster, receiver=receiver,
                       smooth=bool(local["smooth"].any()), tri_normals_back=back, visibility=visibility,
                       lit=linked(orig), blockers=linked(orig, "blocker_collection"))
        if any(b.materials[int(m)]["view_bump"] for m in np.unique(local["tri_material"])):
            view_bumped.update(view_objects[key])
    return view_bumped


def export_scene(bpy_scene=None, depsgraph=None, warn=None) -> S.Scene:
    """Convert a bpy Scene (default: the context scene) into a validated ``Scene``.

    depsgraph: the evaluated depsgraph to read (default: the context's); warn:
    callable(str) receiving each warning once (default: ``logging.warning``).
    Raises SceneError for things that cannot be rendered at all (no camera, a
    panoramic camera).
    """
    if bpy_scene is None:
        bpy_scene = bpy.context.scene
    seen_warnings = set()

    def _warn(msg):
        if msg in seen_warnings:
            return
        seen_warnings.add(msg)
        (warn or log.warning)(msg)

    if depsgraph is None:
        if bpy_scene.camera is None:  # fail fast, before evaluating anything
            raise SceneError(f"scene '{bpy_scene.name}' has no camera")
        depsgraph = _default_depsgraph(bpy_scene)
    camera = export_camera(bpy_scene, depsgraph, _warn)
    say_missing_libraries(bpy_scene, _warn)

    b = SceneBuilder(bpy_scene.name)
    b.camera = camera
    add_world(b, bpy_scene, _warn)
    c = getattr(bpy_scene, "cycles", None)
    if c is not None:  # Light Paths > Max Bounces, as Cycles renders with them (bounces.py)
        b.light_paths = np.array([c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces],
                                 np.int64)
    materials = MaterialTable(b, _warn)
    meshes, emitters, mesh_cache, view_objects = _read_instances(b, depsgraph, materials, _warn)
    # bumps are baked once the depsgraph's instances are read (the bake adds a scene of its own)
    bake_bumps(mesh_cache, materials.bump_specs, _warn)
    # Light and Shadow Linking (the receiver and blocker collections of lights and of emissive meshes):
    # the objects each lights, and those that shadow it
    linked = LinkedNames((orig, name) for name, *_, orig in meshes)
    for entry, orig in emitters:
        entry["lit"], entry["blockers"] = linked(orig), linked(orig, "blocker_collection")
    view_bumped = _add_meshes(b, meshes, mesh_cache, view_objects, linked)
    maps = None
    if view_bumped:
        maps = view_maps(bpy_scene, list(view_bumped), camera, _warn)
        if maps is not None:
            b.view_normals, b.view_points = maps
    if maps is None:
        for m in b.materials:
            m["view_bump"] = False
    return b.build()
