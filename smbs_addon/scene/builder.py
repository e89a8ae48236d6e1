"""Build a Scene piece by piece: used by the Blender export, the tests and the CLI.

Everything is given in world space. Names are kept so messages can name objects.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import arrays as S
from ..core.errors import SceneError
from .geometry import triangle_areas


def _names(lit):
    """A Light Linking's object names as a tuple (None: every object)."""
    return None if lit is None else tuple(str(x) for x in lit)


def _unit(v):
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if not n > 0:
        raise SceneError("zero-length direction")
    return v / n


def look_at(origin, target, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """A 4x4 world matrix whose local -Z looks from origin at target (Blender camera/light)."""
    o = np.asarray(origin, float)
    fwd = _unit(np.asarray(target, float) - o)
    upv = np.asarray(up, float)
    if abs(np.dot(fwd, _unit(upv))) > 0.999:
        upv = np.array([0.0, 1.0, 0.0]) if abs(fwd[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = _unit(np.cross(fwd, upv))
    y = np.cross(x, fwd)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, y, -fwd, o
    return m


@dataclass(frozen=True)
class MaterialProps:
    """A material's properties (SceneBuilder.material), with Cycles' defaults. emission: radiance
    (W/m^2/sr) its surface emits beside its own kind (a Principled BSDF's Emission); an emitter's is
    color x strength. Either makes a mesh light of its faces (build). metal: a metal's Fresnel beyond
    its colour (Scene.mat_metal): F82-Tint's B per channel (fresnel FRESNEL_SCHLICK), or n then k per
    channel (FRESNEL_CONDUCTOR), or a glass's Specular Tint less 1. film: a thin film's (thickness nm,
    index) over it (Scene.mat_film; thickness 0: none)."""

    color: tuple = (0.8, 0.8, 0.8)
    ior: float = 1.5
    roughness: float = 0.0
    strength: float = 0.0
    reflect_color: tuple = (1.0, 1.0, 1.0)
    fresnel: int = S.FRESNEL_NONE
    bump_correction: bool = False
    layer: tuple = (0.0,) * 8
    textured: bool = False
    absorb: tuple = (0.0, 0.0, 0.0)
    distribution: int = 1
    view_bump: bool = False
    emission: tuple = (0.0, 0.0, 0.0)
    metal: tuple = (0.0,) * 6
    film: tuple = S.NO_FILM


@dataclass(frozen=True)
class MeshOptions:
    """How a mesh is shaded and takes part (SceneBuilder.mesh). normals: per-vertex normals (V,3) for
    smooth shading; None means flat. visibility: the rays that meet it (S.RAY_* bits, Cycles' Ray
    Visibility). lit: where its faces shine (a mesh light), the names of the objects its light lights
    (Light Linking, Scene.light_links); None: every object. blockers: likewise, the objects that
    shadow it (Shadow Linking, Scene.light_blockers)."""

    normals: object = None
    smooth: object = None
    uvs: object = None
    caster: bool = False
    receiver: bool = False
    face_materials: object = None
    visibility: int = S.RAY_ALL
    lit: object = None
    blockers: object = None


@dataclass(frozen=True)
class LightProps:
    """A light's placement and Cycles settings (SceneBuilder.light). power: watts (point/spot/area) or
    irradiance W/m^2 (sun). matrix, or location (and target, default straight down). visibility: the
    rays that meet it (S.RAY_* bits, Cycles' Ray Visibility); lit: the names of the objects it lights
    (Light Linking, Scene.light_links), None: every object; blockers: the names of the objects that
    shadow it (Shadow Linking, Scene.light_blockers), None: every object."""

    matrix: object = None
    location: object = None
    target: object = None
    power: float = 1000.0
    color: tuple = (1.0, 1.0, 1.0)
    radius: float = 0.0
    soft_falloff: bool = False
    spot_size: float = math.radians(45)
    spot_blend: float = 0.15
    shape: str = "SQUARE"
    size: object = (1.0, 1.0)
    spread: float = math.pi
    angle: float = 0.0
    caustics: bool = True
    visibility: int = S.RAY_ALL
    lit: object = None
    blockers: object = None


class SceneBuilder:
    def __init__(self, name: str = "scene"):
        self.name = name
        self._tris, self._normals, self._uvs, self._obj, self._mat = [], [], [], [], []
        self._back = []  # per object: its tri_normals_back, or None (its tri_normals)
        self.objects: list[dict] = []
        self.materials: list[dict] = []
        self.lights: list[dict] = []
        self.camera = S.Camera()
        self.world_color = np.zeros(3)
        self.world_map, self.world_map_rotation = np.zeros((0, 0, 3), np.float32), np.eye(3)
        self.light_paths = np.full(4, -1, np.int64)  # Cycles' bounce limits (scene.Scene.light_paths)
        # what the camera sees at s x s sub-pixels (Scene.view_normals, view_points)
        self.view_normals = self.view_points = np.zeros((0, 0, 3), np.float32)

    # ------------------------------------------------------------ materials
    def material(self, name, kind, **props) -> int:
        """A material of kind ("diffuse", "conductor", "dielectric", "emitter", or its code) and the
        properties of MaterialProps (by keyword); an existing name returns that material's index."""
        for i, m in enumerate(self.materials):
            if m["name"] == name:
                return i
        p = MaterialProps(**props)
        kind = S.MATERIAL_KINDS.index(kind) if isinstance(kind, str) else int(kind)
        self.materials.append(dict(name=name, kind=kind, color=np.asarray(p.color, float),
                                   reflect_color=np.asarray(p.reflect_color, float), ior=float(p.ior),
                                   roughness=float(p.roughness), strength=float(p.strength),
                                   fresnel=int(p.fresnel), bump_correction=bool(p.bump_correction),
                                   layer=np.asarray(p.layer, float), textured=bool(p.textured),
                                   absorb=np.broadcast_to(np.asarray(p.absorb, float), (3,)).copy(),
                                   distribution=int(p.distribution), view_bump=bool(p.view_bump),
                                   emission=np.broadcast_to(np.asarray(p.emission, float), (3,)).copy(),
                                   metal=np.broadcast_to(np.asarray(p.metal, float), (6,)).copy(),
                                   film=np.asarray(p.film, float).reshape(2).copy()))
        return len(self.materials) - 1

    # --------------------------------------------------------------- meshes
    def mesh(self, name, vertices, faces, material, **options) -> int:
        """Add a mesh. faces: (F,3) triangles or (F,4) quads (split 0-1-2, 0-2-3); material: a material
        index, or a name already defined; options: MeshOptions (by keyword)."""
        o = MeshOptions(**options)
        normals, smooth, uvs, face_materials = o.normals, o.smooth, o.uvs, o.face_materials
        V = np.asarray(vertices, float).reshape(-1, 3)
        F = np.asarray(faces, np.int64)
        if F.ndim != 2 or F.shape[1] not in (3, 4):
            raise SceneError(f"object '{name}': faces must be triangles or quads")
        if F.shape[1] == 4:
            F = np.concatenate([F[:, [0, 1, 2]], F[:, [0, 2, 3]]])
        if F.size and (F.min() < 0 or F.max() >= len(V)):
            raise SceneError(f"object '{name}': face index out of range")
        if isinstance(material, str):
            material = [m["name"] for m in self.materials].index(material)
        tv = V[F]
        if normals is not None:
            N = np.asarray(normals, float).reshape(-1, 3)
            tn = N[F]
        else:
            fn = np.cross(tv[:, 1] - tv[:, 0], tv[:, 2] - tv[:, 0])
            ln = np.linalg.norm(fn, axis=1, keepdims=True)
            fn = np.divide(fn, ln, out=np.zeros_like(fn), where=ln > 0)
            tn = np.repeat(fn[:, None, :], 3, axis=1)
        if uvs is not None:
            tu = np.asarray(uvs, float).reshape(-1, 2)[F]
        else:
            tu = np.broadcast_to(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), (len(F), 3, 2))
        oid = len(self.objects)
        self.objects.append(dict(name=name, caster=bool(o.caster), receiver=bool(o.receiver),
                                 smooth=bool(normals is not None if smooth is None else smooth),
                                 visibility=int(o.visibility), lit=_names(o.lit), blockers=_names(o.blockers)))
        self._tris.append(tv)
        self._normals.append(tn)
        self._back.append(None)
        self._uvs.append(np.array(tu))
        self._obj.append(np.full(len(F), oid, np.int32))
        fm = (np.full(len(F), material, np.int32) if face_materials is None
              else np.asarray(face_materials, np.int32))
        self._mat.append(fm)
        return oid

    def mesh_corners(self, name, tri_vertices, tri_normals, tri_uvs, tri_material,
                     caster=False, receiver=False, smooth=False, tri_normals_back=None, visibility=S.RAY_ALL,
                     lit=None, blockers=None) -> int:
        """Add an object from per-triangle arrays (the Blender export's entry point).

        tri_vertices, tri_normals: (T,3,3) world positions and unit shading normals per
        corner; tri_uvs: (T,3,2) or None; tri_material: (T,) material indices (already
        defined with ``material``); smooth: whether any face is smooth shaded;
        tri_normals_back: (T,3,3) the normals a ray meets from behind (Scene.tri_normals_back),
        None: tri_normals; visibility: the rays that meet it (S.RAY_* bits); lit, blockers: as mesh's.
        """
        tv = np.asarray(tri_vertices, float).reshape(-1, 3, 3)
        T = len(tv)
        tn = np.asarray(tri_normals, float).reshape(-1, 3, 3)
        if tn.shape != tv.shape:
            raise SceneError(f"object '{name}': {len(tn)} normal triples for {T} triangles")
        if tri_uvs is None:
            tu = np.broadcast_to(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), (T, 3, 2))
        else:
            tu = np.asarray(tri_uvs, float).reshape(-1, 3, 2)
            if len(tu) != T:
                raise SceneError(f"object '{name}': {len(tu)} UV triples for {T} triangles")
        fm = np.broadcast_to(np.asarray(tri_material, np.int32), (T,))
        if T and (fm.min() < 0 or fm.max() >= len(self.materials)):
            raise SceneError(f"object '{name}': material index out of range")
        tb = None if tri_normals_back is None else np.asarray(tri_normals_back, float).reshape(-1, 3, 3)
        if tb is not None and tb.shape != tv.shape:
            raise SceneError(f"object '{name}': {len(tb)} back normal triples for {T} triangles")
        oid = len(self.objects)
        self.objects.append(dict(name=name, caster=bool(caster), receiver=bool(receiver),
                                 smooth=bool(smooth), visibility=int(visibility), lit=_names(lit),
                                 blockers=_names(blockers)))
        self._tris.append(tv)
        self._normals.append(tn)
        self._back.append(tb)
        self._uvs.append(np.array(tu))
        self._obj.append(np.full(T, oid, np.int32))
        self._mat.append(np.array(fm, np.int32))
        return oid

    def plane(self, name, center, size, material, normal=(0, 0, 1), **kw) -> int:
        """A flat rectangle of size (sx, sy) centred at center, facing normal."""
        n = _unit(normal)
        m = look_at(np.zeros(3), -n)  # local -Z = -n, so local +Z = n
        sx, sy = (size, size) if np.isscalar(size) else size
        c = np.asarray(center, float)
        corners = [(-sx / 2, -sy / 2), (sx / 2, -sy / 2), (sx / 2, sy / 2), (-sx / 2, sy / 2)]
        V = [c + a * m[:3, 0] + b * m[:3, 1] for a, b in corners]
        return self.mesh(name, V, [[0, 1, 2, 3]], material, **kw)

    def uv_sphere(self, name, center, radius, material, segments=64, rings=32, smooth=True, **kw):
        c = np.asarray(center, float)
        th = np.linspace(0, math.pi, rings + 1)
        ph = np.linspace(0, 2 * math.pi, segments + 1)[:-1]
        T, P = np.meshgrid(th, ph, indexing="ij")
        dirs = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
        V = c + radius * dirs
        faces = []
        for i in range(rings):
            for j in range(segments):
                a = i * segments + j
                b = i * segments + (j + 1) % segments
                cc, d = a + segments, b + segments
                if i > 0:
                    faces.append([a, cc, b])
                if i < rings - 1:
                    faces.append([b, cc, d])
        return self.mesh(name, V, faces, material, normals=dirs if smooth else None, **kw)

    # --------------------------------------------------------------- lights
    def light(self, name, type, **props) -> int:
        """A light of type ("POINT", "SPOT", "AREA", "SUN") and the properties of LightProps (by
        keyword); a world: see world()."""
        p = LightProps(**props)
        matrix = p.matrix
        if matrix is None:
            loc = np.zeros(3) if p.location is None else p.location
            tgt = np.asarray(loc, float) - np.array([0, 0, 1.0]) if p.target is None else p.target
            matrix = look_at(loc, tgt)
        size = (p.size, p.size) if np.isscalar(p.size) else tuple(p.size)
        self.lights.append(dict(
            name=name, type=S.LIGHT_TYPES.index(type), matrix=np.asarray(matrix, float),
            color=np.asarray(p.color, float) * float(p.power), radius=float(p.radius),
            soft_falloff=bool(p.soft_falloff), spot_size=float(p.spot_size),
            spot_blend=float(p.spot_blend), shape=S.AREA_SHAPES.index(p.shape),
            size=np.asarray(size, float), spread=float(p.spread), angle=float(p.angle),
            caustics=bool(p.caustics), visibility=int(p.visibility), lit=_names(p.lit), blockers=_names(p.blockers)))
        return len(self.lights) - 1

    def world(self, color, strength=1.0, name="World", caustics=True, image=None, rotation=None,
              visibility=S.RAY_ALL) -> int:
        """A world (Cycles' Background node), baked as a light of its own (S.WORLD): radiance
        color x strength from every direction, or with image, an equirectangular map (H, W, 3),
        rows from the bottom up, scaled by color x strength, looked up at rotation @ d
        (Scene.world_map)."""
        self.world_color = np.asarray(color, float)[:3] * float(strength)
        if image is not None:
            self.world_map = np.asarray(image, np.float32)
            self.world_map_rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        return self.light(name, "WORLD", matrix=np.eye(4), color=self.world_color, power=1.0, caustics=caustics,
                          visibility=visibility)

    # --------------------------------------------------------------- camera
    def set_camera(self, location=None, target=None, matrix=None, **kw) -> S.Camera:
        if matrix is None:
            matrix = look_at(location, target)
        self.camera = S.Camera(matrix_world=np.asarray(matrix, float), **kw)
        return self.camera

    # ---------------------------------------------------------------- build
    def build(self) -> S.Scene:
        def cat(parts, shape, dtype=float):
            return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

        m, ob = self.materials, self.objects
        tri_object, tri_material = cat(self._obj, (0,), np.int32), cat(self._mat, (0,), np.int32)
        tri_vertices = cat(self._tris, (0, 3, 3))
        lt, tri_light = self._mesh_lights(tri_vertices, tri_object, tri_material)
        sc = S.Scene(
            tri_vertices=tri_vertices, tri_normals=cat(self._normals, (0, 3, 3)),
            tri_uvs=cat(self._uvs, (0, 3, 2)), tri_object=tri_object, tri_material=tri_material,
            tri_normals_back=(cat([n if b is None else b for n, b in zip(self._normals, self._back)], (0, 3, 3))
                              if any(b is not None for b in self._back) else np.zeros((0, 3, 3))),
            object_names=[o["name"] for o in ob],
            object_caster=np.array([o["caster"] for o in ob], bool),
            object_receiver=np.array([o["receiver"] for o in ob], bool),
            object_smooth=np.array([o["smooth"] for o in ob], bool),
            mat_names=[x["name"] for x in m],
            mat_kind=np.array([x["kind"] for x in m], np.int32),
            mat_color=np.array([x["color"] for x in m], float).reshape(-1, 3),
            mat_reflect_color=np.array([x["reflect_color"] for x in m], float).reshape(-1, 3),
            mat_ior=np.array([x["ior"] for x in m], float),
            mat_roughness=np.array([x["roughness"] for x in m], float),
            mat_strength=np.array([x["strength"] for x in m], float),
            mat_fresnel=np.array([x["fresnel"] for x in m], np.int32),
            light_names=[x["name"] for x in lt],
            light_type=np.array([x["type"] for x in lt], np.int32),
            light_matrix=np.array([x["matrix"] for x in lt], float).reshape(-1, 4, 4),
            light_color=np.array([x["color"] for x in lt], float).reshape(-1, 3),
            light_radius=np.array([x["radius"] for x in lt], float),
            light_soft_falloff=np.array([x["soft_falloff"] for x in lt], bool),
            light_spot_size=np.array([x["spot_size"] for x in lt], float),
            light_spot_blend=np.array([x["spot_blend"] for x in lt], float),
            light_shape=np.array([x["shape"] for x in lt], np.int32),
            light_size=np.array([x["size"] for x in lt], float).reshape(-1, 2),
            light_spread=np.array([x["spread"] for x in lt], float),
            light_angle=np.array([x["angle"] for x in lt], float),
            light_caustics=np.array([x["caustics"] for x in lt], bool),
            camera=self.camera, world_color=np.asarray(self.world_color, float), name=self.name,
            world_map=self.world_map, world_map_rotation=self.world_map_rotation,
            light_paths=np.asarray(self.light_paths, np.int64),
            mat_bump_correction=np.array([x["bump_correction"] for x in m], bool)
            if any(x["bump_correction"] for x in m) else np.zeros(0, bool),
            mat_layer=np.array([x["layer"] for x in m], float).reshape(-1, 8)
            if any(x["layer"][0] > 0 or x["layer"][4] > 0 or x["layer"][5] > 0 for x in m) else np.zeros((0, 8)),
            mat_textured=np.array([x["textured"] for x in m], bool) if any(x["textured"] for x in m)
            else np.zeros(0, bool),
            mat_absorb=np.array([x["absorb"] for x in m], float).reshape(-1, 3) if any(x["absorb"].max() > 0 for x in m)
            else np.zeros((0, 3)),
            mat_distribution=np.array([x["distribution"] for x in m], np.int64)
            if any(x["distribution"] != 1 for x in m) else np.zeros(0, np.int64),
            mat_view_bump=np.array([x["view_bump"] for x in m], bool) if any(x["view_bump"] for x in m)
            else np.zeros(0, bool),
            mat_emission=np.array([x["emission"] for x in m], float).reshape(-1, 3)
            if any(x["emission"].max() > 0 for x in m) else np.zeros((0, 3)),
            mat_metal=np.array([x["metal"] for x in m], float).reshape(-1, 6)
            if any(np.any(x["metal"] != 0) for x in m) else np.zeros((0, 6)),
            mat_film=np.array([x["film"] for x in m], float).reshape(-1, 2)
            if any(x["film"][0] != 0 for x in m) else np.zeros((0, 2)),
            view_normals=np.asarray(self.view_normals, np.float32),
            view_points=np.asarray(self.view_points, np.float32),
            object_visibility=np.array([o["visibility"] for o in ob], np.int64)
            if any(o["visibility"] != S.RAY_ALL for o in ob) else np.zeros(0, np.int64),
            light_visibility=np.array([x["visibility"] for x in lt], np.int64)
            if any(x["visibility"] != S.RAY_ALL for x in lt) else np.zeros(0, np.int64),
            tri_light=tri_light,
            light_links=self._links(lt, "lit"), light_blockers=self._links(lt, "blockers"),
        )
        sc.validate()
        return sc

    def _links(self, lt, key) -> np.ndarray:
        """Scene.light_links (key "lit") or light_blockers ("blockers") of the lights lt: per light, the
        objects its list names (all where it has none); empty where no light has one."""
        what = "Light Linking" if key == "lit" else "Shadow Linking"
        if all(x.get(key) is None for x in lt):
            return np.zeros((0, 0), bool)
        index = {}
        for o, ob in enumerate(self.objects):
            index.setdefault(ob["name"], o)
        links = np.ones((len(lt), len(self.objects)), bool)
        for li, x in enumerate(lt):
            if x.get(key) is None:
                continue
            links[li] = False
            for name in x[key]:
                if name not in index:
                    raise SceneError(f"light '{x['name']}': its {what} names object '{name}', which the scene "
                                     "does not hold")
                links[li, index[name]] = True
        return links

    @staticmethod
    def _radiance(x) -> np.ndarray:
        """A material's emitted radiance: an emitter's colour x strength, and its emission."""
        own = np.asarray(x["color"], float) * x["strength"] if x["kind"] == S.EMITTER else np.zeros(3)
        return own + x["emission"]

    def _mesh_lights(self, tv, tri_object, tri_material):
        """The lights, then a MESH light per object and material of positive radiance (_radiance) on its
        triangles, named after the object (and the material, where the object has more
        than one that shines), seen by the rays that see the object; and Scene.tri_light (empty: none)."""
        lt = list(self.lights)
        glow = [self._radiance(x) for x in self.materials]
        shines = [j for j, g in enumerate(glow) if g.max() > 0]
        if not shines or not len(tv):
            return lt, np.zeros(0, np.int32)
        tri_light = np.full(len(tv), -1, np.int32)
        glows = np.flatnonzero(np.isin(tri_material, shines))
        # (object, material) pairs in object order, then material order; each pair's triangles
        pairs, which = np.unique(np.stack([tri_object[glows], tri_material[glows]], axis=1), axis=0,
                                 return_inverse=True)
        which = which.reshape(-1)
        order = np.argsort(which, kind="stable")
        starts = np.searchsorted(which[order], np.arange(len(pairs) + 1))
        per_object = np.bincount(pairs[:, 0], minlength=len(self.objects))
        for k, (o, j) in enumerate(pairs):
            tris = glows[order[starts[k]:starts[k + 1]]]
            obj, x = self.objects[int(o)], self.materials[int(j)]
            v = tv[tris]
            area = triangle_areas(v)
            mid = v.mean(axis=1)
            c = (area @ mid) / area.sum() if area.sum() > 0 else mid.mean(axis=0)
            matrix = np.eye(4)
            matrix[:3, 3] = c
            tri_light[tris] = len(lt)
            lt.append(dict(
                name=obj["name"] if per_object[o] == 1 else f"{obj['name']}/{x['name']}", type=S.MESH,
                matrix=matrix, color=glow[int(j)],
                radius=float(np.sqrt(np.max(np.sum((v - c) ** 2, axis=2)))), soft_falloff=False,
                spot_size=0.0, spot_blend=0.0, shape=S.SQUARE, size=np.zeros(2), spread=math.pi, angle=0.0,
                caustics=True, visibility=int(obj.get("visibility", S.RAY_ALL)), lit=obj.get("lit"),
                blockers=obj.get("blockers")))
        return lt, tri_light
