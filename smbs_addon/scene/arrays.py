"""Scene arrays: meshes, materials, lights and camera as plain numpy arrays.

This is the contract between the Blender export (``export.py``) and the render
core. Nothing here imports ``bpy``. All geometry is world space, float64, in
Blender's units and conventions (Z up, camera looking down its local -Z).

A scene is saved and loaded as a single ``.npz`` file (``save`` / ``load``).
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import SceneError
# the codes and limits live in constants.py; the scene's module re-exports them (scene.arrays.DIFFUSE, ...)
from .constants import (  # noqa: F401
    AREA, AREA_SHAPES, CONDUCTOR, DIELECTRIC, DIFFUSE, DISK, DISTANT, ELLIPSE, EMITTER, FORMAT_VERSION,
    FRESNEL_CONDUCTOR, FRESNEL_MODELS, FRESNEL_NONE, FRESNEL_SCHLICK, LIGHT_TYPES, MATERIAL_KINDS, MAX_BOUNCES,
    MAX_COLOR, MAX_FILTER_WIDTH, MAX_POWER, MESH, NO_FILM, OPTIONAL, ORTHO, PATH_RAYS, PERSP, POINT, RAY_ALL,
    RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_SHADOW, RAY_TRANSMISSION, RECTANGLE, REFRACTION_ONLY, SENSOR_FITS,
    SPOT, SQUARE, SUN, WORLD, flat_axes)
from .validate import check_types, validate


def offset_eps(lo, hi) -> float:
    """The self-intersection offset for geometry within [lo, hi]: a few float32 ulps of the
    largest coordinate (tracer.Tracer.eps)."""
    extent = float(max(np.abs(lo).max(initial=0), np.abs(hi).max(initial=0)))
    d = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    return 4e-6 * (extent + (d if d > 0 else 1.0))


def column_bounds(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) per column of v (N, 3): column by column, ~25x faster than numpy's reduction
    over axis 0 with 3 columns; raises on N = 0 as that reduction does."""
    return (np.array([v[:, c].min() for c in range(3)]), np.array([v[:, c].max() for c in range(3)]))


@dataclass
class Camera:
    """A Blender camera with the render settings that shape the image."""

    matrix_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    type: int = PERSP
    lens: float = 50.0  # focal length, mm
    sensor_width: float = 36.0
    sensor_height: float = 24.0
    sensor_fit: str = "AUTO"
    ortho_scale: float = 6.0
    shift_x: float = 0.0
    shift_y: float = 0.0
    clip_start: float = 0.1
    clip_end: float = 1000.0
    resolution_x: int = 1920
    resolution_y: int = 1080
    resolution_percentage: int = 100
    pixel_aspect_x: float = 1.0
    pixel_aspect_y: float = 1.0
    use_border: bool = False
    border: tuple = (0.0, 1.0, 0.0, 1.0)  # min_x, max_x, min_y, max_y (fractions, y up)
    use_crop_to_border: bool = False
    filter_width: float = 1.5  # Cycles pixel filter width (Blackman-Harris), pixels

    @property
    def width(self) -> int:
        return max(1, int(self.resolution_x * self.resolution_percentage // 100))

    @property
    def height(self) -> int:
        return max(1, int(self.resolution_y * self.resolution_percentage // 100))


@dataclass
class Scene:
    """Triangles, materials, lights and a camera, all as numpy arrays.

    Triangles: ``tri_vertices`` (T,3,3) world positions; ``tri_normals`` (T,3,3)
    shading normals per corner (equal to the face normal for flat shading);
    ``tri_uvs`` (T,3,2); ``tri_object`` (T,) index into the object tables;
    ``tri_material`` (T,) index into the material tables.
    """

    tri_vertices: np.ndarray
    tri_normals: np.ndarray
    tri_uvs: np.ndarray
    tri_object: np.ndarray
    tri_material: np.ndarray
    # objects
    object_names: list
    object_caster: np.ndarray  # Cycles is_caustics_caster
    object_receiver: np.ndarray  # Cycles is_caustics_receiver
    object_smooth: np.ndarray  # any smooth-shaded face
    # materials
    mat_names: list
    mat_kind: np.ndarray  # DIFFUSE, CONDUCTOR, DIELECTRIC, EMITTER
    mat_color: np.ndarray  # (M,3): albedo / F0 / transmission colour / emission colour
    mat_reflect_color: np.ndarray  # (M,3): dielectric reflection tint
    mat_ior: np.ndarray  # (M,)
    mat_roughness: np.ndarray  # (M,)
    mat_strength: np.ndarray  # (M,) emission strength (radiance, W/m^2/sr)
    mat_fresnel: np.ndarray  # (M,) Fresnel model (FRESNEL_NONE, FRESNEL_SCHLICK, REFRACTION_ONLY, FRESNEL_CONDUCTOR)
    # lights
    light_names: list
    light_type: np.ndarray  # (L,) POINT, SPOT, AREA, SUN, WORLD
    light_matrix: np.ndarray  # (L,4,4) world matrix (scale removed for AREA sizes)
    light_color: np.ndarray  # (L,3) colour x power (W), x strength (sun, W/m^2) or radiance (world)
    light_radius: np.ndarray  # (L,) point/spot radius (shadow_soft_size)
    light_soft_falloff: np.ndarray  # (L,) bool
    light_spot_size: np.ndarray  # (L,) full cone angle, radians
    light_spot_blend: np.ndarray  # (L,)
    light_shape: np.ndarray  # (L,) SQUARE..ELLIPSE
    light_size: np.ndarray  # (L,2) area size x, y (world units, scale applied)
    light_spread: np.ndarray  # (L,) area spread, radians
    light_angle: np.ndarray  # (L,) sun angular diameter, radians
    light_caustics: np.ndarray  # (L,) Cycles is_caustics_light
    camera: Camera = field(default_factory=Camera)
    world_color: np.ndarray = field(default_factory=lambda: np.zeros(3))  # a constant world (its light: S.WORLD)
    name: str = "scene"
    # Cycles' Light Paths bounce limits (bounces.Limits): max, diffuse, glossy, transmission;
    # -1: none (a scene built in code, or saved before they were exported)
    light_paths: np.ndarray = field(default_factory=lambda: np.full(4, -1, np.int64))
    # (M,) bool: Cycles' Material > Settings > Bump Map Correction (on by default in Blender): a
    # smooth-shaded mirror or glass bends its shading normal towards the geometric one where the
    # reflection of the eye's direction would dip under the surface (optics.valid_reflection1);
    # empty: off for every material (a scene built in code, or saved before it was exported)
    mat_bump_correction: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    # (M,5): how a diffuse material departs from Lambert, as Cycles shades it (layer.py): the
    # dielectric glossy coat over it (a Principled BSDF's): its index (0: none), Principled
    # Roughness, Specular Tint's largest channel and the weight (1 - Metallic)(1 - Transmission)
    # that mat_color holds (the diffuse then weighs 1 - A(mu) towards the eye); then the diffuse's
    # own roughness (Oren-Nayar sigma; 0: Lambert); then the Principled clear coat over it all:
    # Coat Weight (0: none), Coat IOR, Coat Roughness. Empty: Lambert everywhere (a scene built in
    # code, or saved before they were exported)
    mat_layer: np.ndarray = field(default_factory=lambda: np.zeros((0, 8)))
    # (M,) bool: a diffuse material whose colour is a texture (an image or procedural on its Base
    # Color): mat_color is a stand-in; where the camera sees it directly the bake also keeps the
    # caustic per unit albedo (BakeResult.per_albedo) for the render's Diffuse Color pass to
    # multiply. Empty: none (a scene built in code, or saved before it was exported)
    mat_textured: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    # (M,3): a glass's Volume Absorption, the absorption coefficient per unit length ((1 - Color) x
    # Density, as Cycles takes it): light crossing the glass over a length d keeps exp(-absorb d).
    # Empty: none (a scene built in code, or saved before it was exported)
    mat_absorb: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # (M,) int: a rough mirror's or glass's microfacet distribution (rough.py): 0 GGX, 1 Multiscatter
    # GGX (Cycles' energy compensation). Empty: Multiscatter GGX, Blender's default (a scene built in
    # code, or saved before it was exported)
    mat_distribution: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    # (H, W, 3) float32: the world's Environment Texture (equirectangular, linear, pixel rows from
    # the bottom up), whose radiance the WORLD light's colour (the Background's Strength) scales;
    # world_map_rotation (3, 3): a direction d looks the map up at world_map_rotation @ d (the
    # Mapping node's turn). Empty: the world is a constant colour (lights.EnvMap)
    world_map: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.float32))
    world_map_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    # (T,3,3): the shading normals per corner a ray meets from behind (its direction along the
    # geometric normal), where they are not tri_normals: Cycles' Bump node does not flip with the
    # surface, so a bumped surface seen from behind bends the other way (bump.py). Empty: tri_normals
    # from both sides (a scene without bumps, built in code, or saved before they were exported)
    tri_normals_back: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))

    # (M,) bool: a diffuse material whose Normal a Bump or Normal Map node drives; its shading normal
    # is read from view_normals where its point projects (eye.view_bumped). Empty: none
    mat_view_bump: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    # (H s, W s, 3) float32 each, top row first: what Cycles' camera rays meet first on the bumped
    # receivers alone through the centres of s x s sub-pixels of the whole frame (its Normal and
    # Position passes at s times the resolution, a sample each, in world space): the shading normal
    # a bump bends there and the point, for mat_view_bump's receivers. The camera at their resolution frames them (a bake at
    # another resolution, auto's pilots, reads them through it: eye.view_tables). Empty: none
    view_normals: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.float32))
    view_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 3), np.float32))
    # (O,) and (L,) int: the rays each object and light is visible to (RAY_* bits, Cycles' Ray
    # Visibility). Empty: every ray (a scene built in code, or saved before they were exported)
    object_visibility: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    light_visibility: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    # (T,) int: the MESH light each triangle shines as (-1: none). Empty: no mesh light (a scene
    # saved before they were baked). A MESH light's light_color is its radiance (W/m^2/sr: an
    # Emission shader's Color x Strength), the translation of its light_matrix its triangles'
    # centroid and light_radius the distance from there to its farthest corner
    tri_light: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    # (M,3): radiance (W/m^2/sr) a material emits beside its own kind (a Principled BSDF's Emission
    # Color x Strength; its faces are then a MESH light too). Empty: none
    mat_emission: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # (M,6): a metal's Fresnel beyond mat_color: for FRESNEL_SCHLICK the F82-Tint model's B per
    # channel, then what a shader mix's other parts weigh (1 - w: a Principled metal's dielectric coat
    # covers (1 - Metallic) w of it, not 1 - Metallic w; zeros unmixed), for FRESNEL_CONDUCTOR the
    # complex index's n then k per channel; for a glass, its Specular Tint less 1 (then zeros). Empty:
    # B = 0 everywhere (plain Schlick), no mix, no physical conductor and no tinted glass
    mat_metal: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    # (M,2): a thin film over a glass, a metal or a Principled BSDF's dielectric coat (Thin Film Thickness
    # in nm, Thin Film IOR), whose iridescence Cycles computes per channel (thinfilm.py); a thickness of
    # thinfilm.CUTOFF or less is none. Empty: none anywhere
    mat_film: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    # (L, O) bool: Cycles' Light Linking, the objects each light lights (its receiver collection, as
    # Blender resolves Include and Exclude). Cycles asks it of the object a path leaves last before
    # the light: of a caustic, the mirror or glass the light comes through last (or the diffuse surface
    # it lit, for light that meets more than one), never the receiver the camera sees. Empty: every
    # light lights every object
    light_links: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))
    # (L, O) bool: Cycles' Shadow Linking, the objects that shadow each light (its blocker collection).
    # Cycles asks it of the rays that reach the light: the path's last segment, from the object it leaves
    # last, passes the objects that do not shadow the light (its "dedicated light" rays), and the path
    # that meets such an object goes on from it as well. Empty: every object shadows every light
    light_blockers: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), bool))

    # ------------------------------------------------------------------ derived
    def mesh_light(self, li: int):
        """MESH light li's triangles, for sampling points on it in proportion to area: (indices (K,),
        corners (K, 3, 3), unit geometric normals (K, 3), cumulative areas (K,), total area), kept
        from validate() on."""
        def compute():
            idx = np.flatnonzero(self.tri_light == li) if self.tri_light.size else np.zeros(0, np.int64)
            tv = np.ascontiguousarray(self.tri_vertices[idx], np.float64)
            c = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
            a2 = np.sqrt(np.einsum("ij,ij->i", c, c))
            ng = c / np.maximum(a2, 1e-300)[:, None]
            cdf = np.cumsum(0.5 * a2)
            return idx, tv, np.ascontiguousarray(ng), cdf, float(cdf[-1]) if len(cdf) else 0.0

        return self.derived(("mesh_light", int(li)), compute)

    def textured_materials(self) -> np.ndarray | None:
        """(M,) bool: the materials whose colour is a texture (mat_textured read as flags: a scene
        built in code may hold 0/1 numbers), or None where there is none."""
        t = np.asarray(self.mat_textured, bool)
        return t if t.any() else None

    def caustic_flags(self) -> np.ndarray:
        """Cycles' Shadow Caustics flags of the lights that have one: every light's but a mesh light's (it
        has none, and is always baked: light_caustics True), which the AUTO flags mode reads to tell
        whether the user flags lights at all."""
        return self.light_caustics[self.light_type != MESH]

    def lit_by(self, li: int) -> np.ndarray:
        """(O,) bool: the objects light li lights (Light Linking, light_links; all where it has none)."""
        if not self.light_links.size:
            return np.ones(len(self.object_names), bool)
        return np.asarray(self.light_links[li], bool)

    def unshadowing(self, li: int) -> np.ndarray | None:
        """(O,) bool: the objects that do not shadow light li (Shadow Linking, light_blockers), which the
        segment reaching it passes; None where every object does."""
        if not self.light_blockers.size or bool(np.all(self.light_blockers[li])):
            return None
        return ~np.asarray(self.light_blockers[li], bool)

    def light_linked(self, li: int) -> bool:
        """Does Light Linking keep light li from some object?"""
        return bool(self.light_links.size) and not bool(np.all(self.light_links[li]))

    def light_seen_by(self, li: int, ray: int) -> bool:
        """Do rays of kind ray (RAY_*) meet light li (Cycles' Ray Visibility)?"""
        return not self.light_visibility.size or bool(int(self.light_visibility[li]) & ray)

    def chain_lit(self, li: int, types: str) -> bool:
        """Can a chain of type types (letters from the receiver's side) take light li's light: is the
        light visible to the ray leaving its last vertex (a glossy ray after an R, a transmission ray
        after a T)?"""
        return self.light_seen_by(li, RAY_GLOSSY if types[-1] == "R" else RAY_TRANSMISSION)

    def camera_hidden(self) -> np.ndarray:
        """(O,) bool: the objects camera rays do not meet (their Ray Visibility), which the camera sees
        through; empty where it sees every object."""
        hidden = (self.hidden_kinds() & RAY_CAMERA) != 0
        return hidden if hidden.any() else np.zeros(0, bool)

    def hidden_kinds(self) -> np.ndarray:
        """(O,) int: the kinds of a path's rays (RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION
        bits) each object does not meet (its Ray Visibility): such a ray passes it. Empty where every
        object meets them all."""
        if not self.object_visibility.size:
            return np.zeros(0, np.int64)
        hid = (~np.asarray(self.object_visibility, np.int64)) & (RAY_CAMERA | PATH_RAYS)
        return hid if hid.any() else np.zeros(0, np.int64)

    def object_seen_by(self, o: int, ray: int) -> bool:
        """Do rays of kind ray (RAY_*) meet object o (Cycles' Ray Visibility)?"""
        return not self.object_visibility.size or bool(int(self.object_visibility[o]) & ray)

    @property
    def n_tris(self) -> int:
        return int(self.tri_vertices.shape[0])

    @property
    def n_lights(self) -> int:
        return int(self.light_type.shape[0])

    def derived(self, key, compute):
        """compute(), kept per key from validate() on while the geometry arrays stay the same
        objects (bounds, seeders, planarity: what a bake would otherwise derive again per chunk).
        Before validate(), or once tri_vertices or tri_object is another array, compute() runs
        every time. A bake validates first and does not change its scene, so a scene edited in
        place between bakes is read afresh."""
        memo = self._memo()
        if memo is None:
            return compute()
        if key not in memo[1]:
            memo[1][key] = compute()
        return memo[1][key]

    def _memo(self):
        memo = self.__dict__.get("_geometry_memo")
        return memo if memo is not None and memo[0] == (id(self.tri_vertices), id(self.tri_object)) else None

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        def compute():
            if self.n_tris == 0:
                return np.zeros(3), np.zeros(3)
            return column_bounds(self.tri_vertices.reshape(-1, 3))

        lo, hi = self.derived("bounds", compute)
        return lo.copy(), hi.copy()

    @property
    def scale(self) -> float:
        """A length for relative tolerances: the diagonal of the geometry's bounds."""
        lo, hi = self.bounds()
        d = float(np.linalg.norm(hi - lo))
        return d if d > 0 else 1.0

    def _every_object_bounds(self) -> dict:
        """{object: (lo, hi)} of the objects with triangles, all at once: one sort, not a mask per
        object."""
        order = np.argsort(self.tri_object, kind="stable")
        objs, start = np.unique(self.tri_object[order], return_index=True)
        if len(objs) == 0:
            return {}
        v = self.tri_vertices[order]
        lo = np.minimum(np.minimum(v[:, 0], v[:, 1]), v[:, 2])
        hi = np.maximum(np.maximum(v[:, 0], v[:, 1]), v[:, 2])
        lo = np.stack([np.minimum.reduceat(lo[:, c], start) for c in range(3)], axis=1)
        hi = np.stack([np.maximum.reduceat(hi[:, c], start) for c in range(3)], axis=1)
        return {int(o): (lo[i], hi[i]) for i, o in enumerate(objs)}

    def object_bounds(self, obj: int) -> tuple[np.ndarray, np.ndarray]:
        got = self.derived("object_bounds", self._every_object_bounds).get(int(obj)) \
            if self._memo() is not None else None
        if got is None:  # not validated, or no triangles (raises, as numpy's reduction of nothing does)
            return column_bounds(self.tri_vertices[self.tri_object == obj].reshape(-1, 3))
        return got[0].copy(), got[1].copy()

    def object_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Every object's bounding box: (lo (O,3), hi (O,3), has (O,) whether it has triangles;
        zeros where not), float64, kept like object_bounds (read-only arrays)."""
        def compute():
            O = len(self.object_names)
            lo, hi, has = np.zeros((O, 3)), np.zeros((O, 3)), np.zeros(O, bool)
            for o, (a, b) in self.derived("object_bounds", self._every_object_bounds).items():
                lo[o], hi[o], has[o] = a, b, True
            for x in (lo, hi, has):
                x.flags.writeable = False
            return lo, hi, has

        return self.derived("object_boxes", compute)

    # ---------------------------------------------------------------- validate
    def validate(self) -> None:
        """Check shapes and values (validate.py); raise SceneError naming what is wrong. Starts the
        geometry memo (_memo) afresh, kept only if the scene is valid."""
        self.__dict__.pop("_geometry_memo", None)
        validate(self)
        self.__dict__["_geometry_memo"] = ((id(self.tri_vertices), id(self.tri_object)), {})

    # -------------------------------------------------------------- save/load
    def save(self, path) -> None:
        """Write the scene as a .npz: through a temporary file beside path, renamed over it (a failed
        write leaves the old file and no temporary)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp.npz")
        try:
            tmp.write_bytes(self.npz_bytes())
            tmp.replace(path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise

    def digest(self) -> str:
        """16 hex digits of a digest of every array and value of the scene (a frame's EXR records it:
        the same digest, settings and code give the same pixels, so a second run may skip the frame)."""
        h = hashlib.sha1()
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            parts = ([np.asarray(getattr(v, cf.name)) for cf in dataclasses.fields(Camera)] if f.name == "camera"
                     else [np.asarray(v, dtype=str) if isinstance(v, list) else np.asarray(v)])
            h.update(f.name.encode())
            for a in parts:
                a = np.ascontiguousarray(a)
                h.update(f"{a.dtype.str}{a.shape}".encode())
                h.update(a.tobytes())
        return h.hexdigest()[:16]

    def npz_bytes(self) -> bytes:
        """The scene's .npz file, in memory (save; the command line's export writes it checked)."""
        arrays = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if f.name == "camera":
                for cf in dataclasses.fields(Camera):
                    arrays["camera." + cf.name] = np.asarray(getattr(v, cf.name))
            elif isinstance(v, list):
                arrays[f.name] = np.asarray(v, dtype=str) if v else np.zeros(0, dtype="<U1")
            else:
                arrays[f.name] = np.asarray(v)
        arrays["format_version"] = np.asarray(FORMAT_VERSION)
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        return buf.getvalue()

    @classmethod
    def load(cls, path) -> "Scene":
        path = Path(path)
        # np.load would return a bare array for a .npy and try pickle on anything else
        if path.is_file() and not zipfile.is_zipfile(path):
            raise SceneError(f"{path}: not a readable scene .npz (not a zip archive)")
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise SceneError(f"{path}: no such file") from None
        except (OSError, ValueError, zipfile.BadZipFile, EOFError, zlib.error, NotImplementedError) as e:
            raise SceneError(f"{path}: not a readable scene .npz ({e})") from None
        try:
            version = int(data.pop("format_version", -1))
        except (TypeError, ValueError):
            version = -1
        if version != FORMAT_VERSION:
            raise SceneError(f"{path}: scene format version {version}, expected {FORMAT_VERSION}")
        check_types(path, data)
        cam_kw = {}
        for cf in dataclasses.fields(Camera):
            key = "camera." + cf.name
            if key not in data:
                raise SceneError(f"{path}: missing camera field '{cf.name}'")
            v = data.pop(key)
            cam_kw[cf.name] = (v if cf.name == "matrix_world" else
                               tuple(v.tolist()) if cf.name == "border" else v.item())
        kw = {}
        for f in dataclasses.fields(cls):
            if f.name == "camera":
                continue
            if f.name not in data:
                if f.name in OPTIONAL:  # written by a later version than the file's
                    continue
                raise SceneError(f"{path}: missing array '{f.name}'")
            v = data[f.name]
            if f.name in ("object_names", "mat_names", "light_names"):
                v = [str(s) for s in v.tolist()]
            elif f.name == "name":
                v = str(v)
            kw[f.name] = v
        scene = cls(camera=Camera(**cam_kw), **kw)
        scene.validate()
        return scene


def empty_scene(**kw) -> Scene:
    """A scene with no geometry, materials or lights (filled in by builders)."""
    z3 = np.zeros((0, 3, 3))
    base = dict(
        tri_vertices=z3, tri_normals=z3.copy(), tri_uvs=np.zeros((0, 3, 2)),
        tri_object=np.zeros(0, np.int32), tri_material=np.zeros(0, np.int32),
        object_names=[], object_caster=np.zeros(0, bool), object_receiver=np.zeros(0, bool),
        object_smooth=np.zeros(0, bool),
        mat_names=[], mat_kind=np.zeros(0, np.int32), mat_color=np.zeros((0, 3)),
        mat_reflect_color=np.zeros((0, 3)), mat_ior=np.zeros(0), mat_roughness=np.zeros(0),
        mat_strength=np.zeros(0), mat_fresnel=np.zeros(0, np.int32),
        light_names=[], light_type=np.zeros(0, np.int32), light_matrix=np.zeros((0, 4, 4)),
        light_color=np.zeros((0, 3)), light_radius=np.zeros(0),
        light_soft_falloff=np.zeros(0, bool), light_spot_size=np.zeros(0),
        light_spot_blend=np.zeros(0), light_shape=np.zeros(0, np.int32),
        light_size=np.zeros((0, 2)), light_spread=np.zeros(0), light_angle=np.zeros(0),
        light_caustics=np.zeros(0, bool),
    )
    base.update(kw)
    return Scene(**base)
