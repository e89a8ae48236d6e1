"""The renders and bakes the export asks Cycles for, each in a scene of its own that is removed again
(the user's scene is not touched): an Emission bake of what drives a bumped mirror's or glass's Normal
at a mesh's vertices (``bake_normals``: bump.py bends the normals from it), and a render of the Normal
and Position passes where the camera sees the bumped receivers (``view_maps``: Scene.view_normals,
view_points)."""
from __future__ import annotations

import math
import tempfile
from pathlib import Path

import bpy
import numpy as np

from ..io.exr import read_passes
from .nodes import follow


def _emission_bake():
    """Cycles' Emission bake of the context's active object to its active colour attribute."""
    return bpy.ops.object.bake(type="EMIT", target="VERTEX_COLORS")


def bake_normals(source, co, tv, slot, uvs, uv_name, kind) -> np.ndarray:
    """Cycles' values at every vertex of a mesh (co, tv in the object's space, slot: material slot per
    triangle) of what drives its bumped materials' Normals: kind "height", a Bump node's Height per
    vertex (V,); kind "vector", the BSDF's Normal input per corner (T, 3, 3), in world space. A copy
    of the mesh in a scene of its own, each such material copied with that socket wired to an
    Emission, an Emission bake to a float colour attribute. Everything made is removed again; the
    user's scene is not touched."""
    made = []
    try:
        me = bpy.data.meshes.new("smbs_bump")
        made.append((bpy.data.meshes, me))
        me.vertices.add(len(co))
        me.vertices.foreach_set("co", co.astype(np.float32).ravel())
        me.loops.add(tv.size)
        me.loops.foreach_set("vertex_index", tv.astype(np.int32).ravel())
        me.polygons.add(len(tv))
        me.polygons.foreach_set("loop_start", np.arange(0, tv.size, 3, dtype=np.int32))
        me.polygons.foreach_set("material_index", slot.astype(np.int32))
        if uvs is not None:
            layer = me.uv_layers.new(name=uv_name or "UVMap")
            layer.uv.foreach_set("vector", uvs.astype(np.float32).ravel())
        me.update()
        loc, size = source["texspace"]
        me.use_auto_texspace = False
        me.texspace_location, me.texspace_size = loc, size
        for entry in source["slots"]:
            if entry is None or entry[0] != kind:
                me.materials.append(None)
                continue
            node_name, mat = entry[1], entry[5]
            copy = mat.copy()
            made.append((bpy.data.materials, copy))
            tree = copy.node_tree
            driver = follow(tree.nodes[node_name].inputs["Height" if kind == "height" else "Normal"])[1]
            for nd in [nd for nd in tree.nodes if nd.type == "OUTPUT_MATERIAL"]:
                tree.nodes.remove(nd)
            em = tree.nodes.new("ShaderNodeEmission")
            em.inputs["Strength"].default_value = 1.0
            out = tree.nodes.new("ShaderNodeOutputMaterial")
            tree.links.new(driver, em.inputs["Color"])
            tree.links.new(em.outputs["Emission"], out.inputs["Surface"])
            out.is_active_output = True
            me.materials.append(copy)
        name = "smbs_height" if kind == "height" else "smbs_normal"
        attr = me.color_attributes.new(name, "FLOAT_COLOR", "POINT" if kind == "height" else "CORNER")
        me.color_attributes.active_color = attr
        ob = bpy.data.objects.new("smbs_bump", me)
        made.insert(0, (bpy.data.objects, ob))
        ob.matrix_world = source["matrix"].T.tolist()
        sc = bpy.data.scenes.new("smbs_bump")
        made.insert(0, (bpy.data.scenes, sc))
        sc.render.engine = "CYCLES"
        sc.cycles.device = "CPU"
        sc.cycles.samples = 1
        sc.collection.objects.link(ob)
        vl = sc.view_layers[0]
        ob.select_set(True, view_layer=vl)
        vl.objects.active = ob
        with bpy.context.temp_override(scene=sc, view_layer=vl, active_object=ob, object=ob,
                                       selected_objects=[ob], selected_editable_objects=[ob]):
            res = _emission_bake()
        if "FINISHED" not in res:
            raise RuntimeError(f"Cycles' bake returned {sorted(res)}")
        values = np.empty((len(co) if kind == "height" else tv.size) * 4, np.float32)
        me.color_attributes[name].data.foreach_get("color", values)
        values = values.reshape(-1, 4).astype(float)
        return values[:, 0] if kind == "height" else values[:, :3].reshape(-1, 3, 3)
    finally:
        for coll, block in made:
            try:
                coll.remove(block)
            except (ReferenceError, RuntimeError):
                pass


VIEW_SUBPIXELS = 2_000_000  # the view maps' sub-pixels at most (two float32 maps of 24 MB)
VIEW_MOST = 4  # sub-pixels per pixel side at most


def plain_passes_render(sc, path, samples: int):
    """Set the copy sc of a scene to render its passes plainly with Cycles on the CPU: to a 32-bit multilayer
    EXR at path, no border, motion blur, compositing or sequencer, a fixed seed, samples per pixel, no
    adaptive sampling, denoising or bounces. Returns its Cycles settings for more."""
    r = sc.render
    r.engine = "CYCLES"
    r.use_border = False
    r.use_motion_blur = False
    r.use_compositing = r.use_sequencer = False
    r.image_settings.media_type = "MULTI_LAYER_IMAGE"
    r.image_settings.color_depth = "32"
    r.filepath = str(path)
    c = sc.cycles
    c.device = "CPU"
    c.samples, c.seed, c.use_animated_seed = samples, 0, False
    c.use_adaptive_sampling = c.use_denoising = False
    c.max_bounces = 0
    return c


def _view_render(sc):
    """Cycles' render of scene sc to its render.filepath."""
    bpy.ops.render.render(write_still=True, scene=sc.name)


def view_maps(bpy_scene, objects, camera, warn):
    """What Cycles' camera rays meet first on the bumped receivers `objects` alone, through the
    centres of s x s sub-pixels of the frame (Scene.view_normals, view_points: its Normal and
    Position passes, a sample per sub-pixel, no bounces, a pixel filter of 0.01): the shading normals
    a bump or normal map bends, as Cycles' own nodes make them, whatever drives them, where nothing
    else hides them (a floor under water, seen through it, is looked up where it projects:
    eye.view_bumped). s is the most (up to VIEW_MOST) that keeps VIEW_SUBPIXELS. A scene of its own
    holds the objects (shared, not copied) and the camera, at the scene's frame; it, its files and a
    Render Result image it made are removed again, the user's scene is not touched. None, said, where
    Cycles cannot render it."""
    W, H = camera.width, camera.height
    s = max(1, min(VIEW_MOST, math.isqrt(max(VIEW_SUBPIXELS // (W * H), 1))))
    sc = None
    results = {im.name for im in bpy.data.images if im.type == "RENDER_RESULT"}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            sc = bpy.data.scenes.new("smbs_view")
            for ob in objects:
                sc.collection.objects.link(ob)
            if bpy_scene.camera.name not in sc.collection.objects:
                sc.collection.objects.link(bpy_scene.camera)
            sc.camera = bpy_scene.camera
            sc.frame_set(bpy_scene.frame_current, subframe=bpy_scene.frame_subframe)
            r, ur = sc.render, bpy_scene.render
            r.resolution_x, r.resolution_y, r.resolution_percentage = W * s, H * s, 100
            r.pixel_aspect_x, r.pixel_aspect_y = ur.pixel_aspect_x, ur.pixel_aspect_y
            c = plain_passes_render(sc, Path(tmp) / "view.exr", samples=1)
            c.filter_width = 0.01  # each sub-pixel's sample at its centre
            vl = sc.view_layers[0]
            vl.use_pass_normal = vl.use_pass_position = True
            _view_render(sc)
            chans = read_passes(r.filepath)
            maps = [np.stack([chans[f"{p}.{a}"] for a in "XYZ"], axis=-1) for p in ("Normal", "Position")]
            if maps[0].shape[:2] != (H * s, W * s):
                raise RuntimeError(f"a render of {maps[0].shape[1]} x {maps[0].shape[0]} pixels")
            return tuple(np.ascontiguousarray(np.nan_to_num(m, nan=0.0, posinf=0.0, neginf=0.0)) for m in maps)
    except Exception as e:  # noqa: BLE001 - Cycles could not render it: the receivers unbumped, and said so
        warn(f"scene '{bpy_scene.name}': the view of its bumped receivers could not be rendered ({e}); the "
             f"caustic on them is shaded with their unbumped normals")
        return None
    finally:
        if sc is not None:
            bpy.data.scenes.remove(sc)
        for im in [im for im in bpy.data.images if im.type == "RENDER_RESULT" and im.name not in results]:
            bpy.data.images.remove(im)  # the render's image, where the file had none
