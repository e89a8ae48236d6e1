"""Blender scene -> smbs ``Scene`` (numpy arrays). The only core module that imports bpy.

``export_scene(bpy_scene)`` walks the evaluated depsgraph (so modifiers, geometry
nodes and instances are included), converts every renderable mesh to world-space
triangles with per-corner shading normals, classifies materials from their node
trees, converts lights and the camera with Cycles' conventions, and returns a
validated ``Scene``. The user's scene is only read: temporary meshes from
``to_mesh()`` are freed with ``to_mesh_clear()``.

Anything that cannot be represented is reported through ``warn`` (a callable
taking one string; by default the messages go to ``logging``) and replaced by a
stated fallback, e.g. an unsupported material becomes diffuse with albedo 0.8.
"""
from __future__ import annotations

import logging
import math

import bpy
import numpy as np

from ..scene import bump
from ..shading import thinfilm
from ..scene import arrays as S
from ..scene.builder import SceneBuilder
from ..core.errors import SceneError
from ..shading.coat import principled_layer
from ..shading.fresnel import conductor_f0, f82_tint_metal
from ..shading.microfacet import GGX, MULTI_GGX, SINGULAR_ALPHA2

log = logging.getLogger(__name__)

DEFAULT_ALBEDO = 0.8
DEFAULT_MATERIAL = "<default diffuse>"
MESH_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
_OLD_NODES_FLAG = bpy.app.version < (5, 0, 0)  # use_nodes is deprecated (always on) in 5.0
_LUMA = np.array([0.2126, 0.7152, 0.0722])  # Rec.709 weights (colour -> float socket)


class _Unsupported(Exception):
    """A material (or world/light node setup) we cannot represent; the text says why."""


# ----------------------------------------------------------------------------- helpers
def _orthonormal(m: np.ndarray) -> np.ndarray:
    """The 4x4 matrix with each of its first three columns normalised (scale removed)."""
    out = np.array(m, float)
    for i in range(3):
        n = np.linalg.norm(out[:3, i])
        if n > 0:
            out[:3, i] /= n
    return out


def _axis_scale(m: np.ndarray) -> np.ndarray:
    return np.linalg.norm(np.asarray(m, float)[:3, :3], axis=0)


def _uses_nodes(idblock) -> bool:
    return bool(getattr(idblock, "use_nodes", True)) if _OLD_NODES_FLAG else True


def _follow(socket):
    """The (node, output socket) feeding an input socket, through reroutes; None if unlinked."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        links = [lk for lk in socket.links if lk.is_valid and not lk.is_muted]
        if not links:
            return None
        node, out = links[0].from_node, links[0].from_socket
        if node.type == "REROUTE":
            socket = node.inputs[0]
            seen += 1
            continue
        return node, out
    return None


def _input(node, name, default):
    """_const of an input a node may lack (older or newer Blender): default where it has none."""
    return _const(node, name) if node.inputs.get(name) is not None else default


def _const(node, name):
    """The constant value of an input socket: its default, or an RGB/Value node feeding it.

    Returns a float or an (3,) array depending on the socket type. Raises _Unsupported
    naming the socket if it is driven by anything else (a texture, a math node, ...).
    """
    sock = node.inputs.get(name)
    if sock is None:
        raise _Unsupported(f"node '{node.name}' has no input '{name}'")
    want_color = sock.type in ("RGBA", "VECTOR")
    src = _follow(sock)
    if src is None:
        val = sock.default_value
    else:
        snode, sout = src
        if snode.type in ("RGB", "VALUE") and not snode.mute:
            val = sout.default_value
        else:
            raise _Unsupported(f"input '{name}' of node '{node.name}' is driven by node "
                               f"'{snode.name}' (a constant is needed)")
    try:
        arr = np.array(val[:], float)
    except TypeError:
        arr = np.array(float(val))
    if want_color:
        return np.broadcast_to(arr, (3,)).astype(float) if arr.ndim == 0 else arr[:3].copy()
    if arr.ndim == 0:
        return float(arr)
    return float(np.dot(arr[:3], _LUMA))


def _colour(node, name):
    """(colour, textured) of a colour input: _const's value, or where a node other than an RGB
    one drives it (an image or procedural texture, a mix of them: something that varies over the
    surface), a stand-in and True: the mean of a Checker Texture's two constant colours or of an
    Image Texture's pixels, else DEFAULT_ALBEDO. Cycles' Diffuse Color pass holds the texture's value where the camera sees
    the surface (BakeResult.per_albedo)."""
    try:
        return _const(node, name), False
    except _Unsupported:
        src = _follow(node.inputs[name])
        if src is None:
            raise
    tex = src[0]
    if tex.type == "TEX_CHECKER":
        try:
            return 0.5 * (_const(tex, "Color1") + _const(tex, "Color2")), True
        except _Unsupported:
            pass
    if tex.type == "TEX_IMAGE" and src[1].name == "Color":
        mean = _image_mean(tex.image)
        if mean is not None:
            return mean, True
    return np.full(3, DEFAULT_ALBEDO), True


MAX_MEAN_PIXELS = 4096 * 4096  # an image's mean is read for its stand-in colour up to this size


def _image_mean(img):
    """The mean linear RGB of an image (_image_linear), or None."""
    rgb = _image_linear(img)
    if rgb is None:
        return None
    mean = rgb.reshape(-1, 3).mean(axis=0, dtype=np.float64)
    return mean if np.all(np.isfinite(mean)) else None


def _image_linear(img, most=MAX_MEAN_PIXELS, read=True):
    """An image's linear RGB (H, W, 3) float32, rows from the bottom up (Cycles reads an 8-bit sRGB
    image through the sRGB curve; float images and the other colour spaces are taken as linear),
    or None: no image, none loaded (a missing file), or one of more than `most` pixels (reading it
    would cost seconds and GBs). read False: an empty (0, 0, 3) array where it could be read."""
    if img is None:
        return None
    try:
        w, h = (int(x) for x in img.size)
        channels = int(img.channels)
    except (AttributeError, RuntimeError, ValueError):
        return None
    if not 0 < w * h <= most or channels < 3:
        return None
    if not read:
        return np.zeros((0, 0, 3), np.float32)
    px = np.empty(w * h * channels, np.float32)
    img.pixels.foreach_get(px)
    rgb = px.reshape(h, w, channels)[:, :, :3]
    if not img.is_float and img.colorspace_settings.name == "sRGB":
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4).astype(np.float32)
    return np.ascontiguousarray(rgb)


def _linked(node, name) -> bool:
    sock = node.inputs.get(name)
    return sock is not None and _follow(sock) is not None


def _output(tree, out_type):
    """The output node Cycles renders from (None if there is none)."""
    out = None
    if hasattr(tree, "get_output_node"):
        try:
            out = tree.get_output_node("CYCLES")
        except (TypeError, RuntimeError):
            out = None
    if out is None:
        outs = [n for n in tree.nodes if n.type == out_type]
        outs.sort(key=lambda n: (not n.is_active_output, getattr(n, "target", "ALL") == "EEVEE"))
        out = outs[0] if outs else None
    return out


def _shader_node(tree, out_type):
    """The shader node linked to the Surface of the active output, through simple cases."""
    out = _output(tree, out_type)
    if out is None:
        raise _Unsupported("node tree has no output node")
    src = _follow(out.inputs["Surface"])
    if src is None:
        return None
    node = src[0]
    for _ in range(64):
        if node.mute:
            raise _Unsupported(f"node '{node.name}' is muted")
        if node.type == "MIX_SHADER" and not _linked(node, "Factor"):
            fac = float(node.inputs[0].default_value)
            if fac <= 0.0 or fac >= 1.0:
                nxt = _follow(node.inputs[1 if fac <= 0.0 else 2])
                if nxt is None:
                    return None
                node = nxt[0]
                continue
        return node
    raise _Unsupported("node tree is too deep")


# --------------------------------------------------------------------------- materials
def _say_textured(mat, stand_in, warn):
    warn(f"material '{mat.name}': its colour is a texture: where the camera sees it, the caustic takes "
         f"the render's Diffuse Color pass (composited); seen through mirrors or glass, and in light it "
         f"passes on, it counts as albedo {float(np.mean(stand_in)):.3g}")


def classify_material(mat, warn) -> dict:
    """Keyword arguments for ``SceneBuilder.material`` (minus the name) for a bpy Material: its
    surface, and a glass's Volume Absorption."""
    kw = _surface_material(mat, warn)
    tree = mat.node_tree
    out = _output(tree, "OUTPUT_MATERIAL") if tree is not None and _uses_nodes(mat) else None
    if kw["kind"] in (S.DIELECTRIC, S.CONDUCTOR) and out is not None and _linked(out, "Displacement"):
        warn(f"material '{mat.name}': its Displacement is linked: its caustic is baked from the undisplaced "
             f"surface, where Cycles' follows the bumps (the mesh's own shape, modifiers included, is used)")
    vol = _follow(out.inputs["Volume"]) if out is not None and out.inputs.get("Volume") is not None else None
    if vol is None or vol[0].mute:
        return kw
    node, why = vol[0], None
    if kw["kind"] != S.DIELECTRIC:
        why = "only a glass's volume is ours"
    elif node.type != "VOLUME_ABSORPTION":
        why = "only Volume Absorption is supported (no scattering, no emission)"
    else:
        try:  # Cycles: absorption (1 - Color) x Density, both clamped at 0
            color = np.maximum(_const(node, "Color"), 0.0)
            kw["absorb"] = np.maximum(1.0 - color, 0.0) * max(float(_const(node, "Density")), 0.0)
        except _Unsupported as e:
            why = str(e)
    if why:
        warn(f"material '{mat.name}': its Volume ('{node.name}') is ignored ({why}): light crosses the object "
             f"unabsorbed and unscattered, where Cycles absorbs or scatters it")
    return kw


def _surface_material(mat, warn) -> dict:
    """classify_material's surface."""
    def diffuse(reason, albedo=None):
        a = DEFAULT_ALBEDO if albedo is None else albedo
        a = np.broadcast_to(np.asarray(a, float), (3,))
        shown = f"{a[0]:g}" if np.all(a == a[0]) else "(" + ", ".join(f"{x:.3g}" for x in a) + ")"
        warn(f"material '{mat.name}': {reason}; treated as diffuse (albedo {shown})")
        return dict(kind=S.DIFFUSE, color=a.copy())

    tree = mat.node_tree
    if tree is None or not _uses_nodes(mat):
        return diffuse("material has no shader nodes", np.array(mat.diffuse_color[:3], float))
    try:
        out = _output(tree, "OUTPUT_MATERIAL")
        if out is None:
            raise _Unsupported("node tree has no output node")
        src = _follow(out.inputs["Surface"])
        if src is None:
            return _black(mat, warn, "nothing is linked to the Material Output's Surface")
        if src[0].type not in _MIXES:
            return _bsdf(src[0], mat, warn, direct=True)
        parts, left = _parts(src[0], mat, warn, 0)
        if not parts and not left:
            return _black(mat, warn, "its shader mix has no closures")
        return _mixed(parts, left, mat, warn)
    except _Unsupported as e:
        return diffuse(str(e))


def _distribution(node, mat, warn, roughness) -> int:
    """A rough mirror's or glass's microfacet distribution (rough.py): Multiscatter GGX or GGX; a
    Beckmann or Ashikhmin-Shirley one is baked as GGX, and said so where the surface is rough."""
    d = getattr(node, "distribution", "MULTI_GGX")
    if d == "MULTI_GGX":
        return MULTI_GGX
    if d != "GGX" and float(roughness) ** 4 > SINGULAR_ALPHA2:
        warn(f"material '{mat.name}': the {d.replace('_', '-').title()} distribution of '{node.name}' is baked "
             f"as GGX (its blur of the caustic a little different from Cycles')")
    return GGX


def _black(mat, warn, why) -> dict:
    """A material that renders black in Cycles (why: its surface has no closure)."""
    warn(f"material '{mat.name}': {why} (renders black in Cycles); treated as black diffuse")
    return dict(kind=S.DIFFUSE, color=np.zeros(3))


_MIXES = ("MIX_SHADER", "ADD_SHADER")
MAX_MIX_DEPTH = 16
# which of a shader mix's groups of parts a material takes when they weigh the same
_RANK = {S.DIELECTRIC: 0, S.CONDUCTOR: 1, S.DIFFUSE: 2, S.EMITTER: 3}
_PART_WORDS = {S.DIELECTRIC: "glass", S.CONDUCTOR: "glossy", S.DIFFUSE: "diffuse", S.EMITTER: "emission"}


def _parts(node, mat, warn, depth):
    """A Mix or Add Shader's closures as Cycles weighs them: ([(weight, material keywords, node
    name)], [(weight, node name, why it is not ours)]), nested mixes flattened (a Mix Shader's factor,
    clamped to 0..1 as Cycles does, weighs its second input and 1 - factor its first; an Add Shader
    weighs both by 1; an empty input adds nothing)."""
    if node.type not in _MIXES:
        return [(1.0, _bsdf(node, mat, warn), node.name)], []
    if node.mute:
        raise _Unsupported(f"node '{node.name}' is muted")
    if depth >= MAX_MIX_DEPTH:
        raise _Unsupported("node tree is too deep")
    ior = _fresnel_index(node) if node.type == "MIX_SHADER" else None
    if ior is not None:
        return [(1.0, _fresnel_mix(node, ior, mat, warn), node.name)], []
    if node.type == "ADD_SHADER":
        inputs = [(1.0, node.inputs[0]), (1.0, node.inputs[1])]
    elif _shadow_ray_factor(node):
        # the fake-shadow trick: shadow rays see the second input (a Transparent BSDF), every other ray
        # the first. No segment of a caustic path is a shadow ray in Cycles (the walks' visibility tests
        # stand for its BSDF-sampled rays), and the direct light its shadow rays let through is in
        # both its renders: the layer takes the first input, exactly
        inputs = [(1.0, node.inputs[1])]
    else:
        try:
            fac = min(max(float(_const(node, node.inputs[0].name)), 0.0), 1.0)
        except _Unsupported as e:
            raise _Unsupported(f"{e}: a Mix Shader's Factor must be a constant") from None
        inputs = [(1.0 - fac, node.inputs[1]), (fac, node.inputs[2])]
    parts, left = [], []
    for w, sock in inputs:
        src = _follow(sock)
        if not w > 0.0 or src is None:
            continue
        try:
            p, lf = _parts(src[0], mat, warn, depth + 1)
        except _Unsupported as e:
            left.append((w, src[0].name, str(e)))
            continue
        parts += [(w * pw, kw, name) for pw, kw, name in p]
        left += [(w * lw, name, why) for lw, name, why in lf]
    return parts, left


def _shadow_ray_factor(mix) -> bool:
    """Is a Mix Shader's Factor Light Path's Is Shadow Ray?"""
    src = _follow(mix.inputs[0])
    return src is not None and not src[0].mute and src[0].type == "LIGHT_PATH" and src[1].name == "Is Shadow Ray"


def _fresnel_index(mix):
    """The index of the Fresnel node (or Layer Weight's Fresnel output) driving a Mix Shader's Factor,
    or None: Cycles' dielectric Fresnel of the incoming direction at the shading normal, for that
    index (Layer Weight: 1 / (1 - Blend)) and its inverse from the back."""
    src = _follow(mix.inputs[0])
    if src is None or src[0].mute:
        return None
    node, out = src
    if node.type == "FRESNEL" or (node.type == "LAYER_WEIGHT" and out.name == "Fresnel"):
        if _linked(node, "Normal"):
            raise _Unsupported(f"the Normal of node '{node.name}' driving the Factor of '{mix.name}' is linked")
        if node.type == "FRESNEL":
            return max(float(_const(node, "IOR")), 1.0 + 1e-5)
        return 1.0 / max(1.0 - float(_const(node, "Blend")), 1e-5)
    return None


def _fresnel_mix(mix, ior, mat, warn) -> dict:
    """A Mix Shader weighed by a Fresnel node: Cycles' old glass (Refraction and Glossy) is a Glass
    BSDF whose reflection and refraction keep their own colours, and Blender's old coated floor
    (Diffuse and Glossy) is a diffuse under a smooth coat of that index (layer.py's weight 1 - F(mu)
    towards the eye: its table at Roughness 0 is exactly that)."""
    sides = []
    for sock in mix.inputs[1:3]:
        src = _follow(sock)
        sides.append(None if src is None else (_bsdf(src[0], mat, warn), src[0].name))
    (a, a_name), (g, g_name) = [s if s is not None else (None, None) for s in sides]
    glossy = g is not None and g["kind"] == S.CONDUCTOR and g.get("fresnel", S.FRESNEL_NONE) == S.FRESNEL_NONE
    if glossy and a is not None and a["kind"] == S.DIELECTRIC and a.get("fresnel") == S.REFRACTION_ONLY \
            and abs(float(a["roughness"]) - float(g["roughness"])) < 1e-6:
        if abs(float(a["ior"]) - ior) > 1e-4:
            warn(f"material '{mat.name}': the Fresnel of Mix Shader '{mix.name}' is of index {ior:.4g}, its "
                 f"refraction of {float(a['ior']):.4g}: taken as one glass of index {float(a['ior']):.4g}")
        return dict(kind=S.DIELECTRIC, color=np.asarray(a["color"], float).copy(),
                    reflect_color=np.asarray(g["color"], float).copy(), ior=float(a["ior"]),
                    roughness=float(a["roughness"]), distribution=int(a.get("distribution", MULTI_GGX)))
    lay = _layer_of(a) if a is not None and a["kind"] == S.DIFFUSE else None
    if glossy and lay is not None and not np.any(lay[[0, 5]] > 0):
        warn(f"material '{mat.name}': its Glossy part '{g_name}' (weighed by the Fresnel of index {ior:.4g}) "
             f"neither casts nor receives caustics; the diffuse under it keeps 1 - Fresnel towards the eye")
        return dict(a, layer=(ior, 0.0, 1.0, lay[3], lay[4], 0.0, 0.0, 0.0))
    raise _Unsupported(f"the Factor of Mix Shader '{mix.name}' is a Fresnel: read for a Refraction BSDF and a "
                       f"Glossy BSDF of one roughness (a glass) or a Diffuse BSDF and a Glossy BSDF (a coated "
                       f"diffuse), in that order, only")


def _group_key(kw):
    """Parts of a mix that add up exactly into one material: the same kind and, for glass and
    mirrors, the same index, roughness, Fresnel and microfacet distribution."""
    k = kw["kind"]
    if k in (S.DIELECTRIC, S.CONDUCTOR):
        fresnel = int(kw.get("fresnel", S.FRESNEL_NONE))
        # physical conductors add up only where their index is the same (F82-Tint's B adds up)
        # (nor do glasses under different Specular Tints: Scene.mat_metal of a glass)
        index = tuple(np.round(kw["metal"], 9)) if fresnel == S.FRESNEL_CONDUCTOR or (
            k == S.DIELECTRIC and np.any(kw.get("metal", np.zeros(6)) != 0)) else ()
        # nor do parts under different thin films
        film = tuple(np.round(kw.get("film", S.NO_FILM), 9)) if kw.get("film", S.NO_FILM)[0] > 0 else ()
        return (k, float(kw.get("ior", 1.5)), float(kw.get("roughness", 0.0)), fresnel,
                int(kw.get("distribution", MULTI_GGX))) + index + film
    return (k,)


def _layer_of(kw):
    lay = np.asarray(kw.get("layer", (0.0,) * 8), float).copy()
    if not lay[3] > 0:
        lay[3] = 1.0  # a diffuse without Cycles' layering: all of its colour is the diffuse's
    return lay


def _mixed(parts, left, mat, warn) -> dict:
    """One material from a shader mix's parts: the group of parts (_group_key) that weighs most (a
    glass or mirror first where they weigh the same), its colours summed by weight, which is what
    Cycles' mix does to each closure; the rest is left out, and said so. A lone part of weight 1 is
    that part unchanged."""
    if len(parts) == 1 and not left and parts[0][0] == 1.0:
        return parts[0][1]
    if not parts:
        why = "; ".join(f"'{name}': {reason}" for _, name, reason in left)
        raise _Unsupported(f"no part of its shader mix is supported ({why})")
    groups: dict = {}
    for w, kw, name in parts:
        groups.setdefault(_group_key(kw), []).append((w, kw, name))
    mass = {k: sum(w for w, _, _ in g) for k, g in groups.items()}
    key = min(groups, key=lambda k: (-round(mass[k], 9), _RANK[k[0]]))
    chosen = groups[key]
    first = chosen[0][1]
    kw = dict(first)
    kind = key[0]
    if kind == S.EMITTER:
        kw["color"] = sum(w * np.asarray(p["color"], float) * float(p.get("strength", 1.0)) for w, p, _ in chosen)
        kw["strength"] = 1.0
    elif kind == S.CONDUCTOR and key[3] in (S.FRESNEL_SCHLICK, S.FRESNEL_CONDUCTOR):
        # a metal's Fresnel is not scaled by its weight: F0 and B are the weighted means (Schlick and the
        # F82 term are affine in them), the weights go to the reflection tint (below)
        total = mass[key] if mass[key] > 0 else 1.0
        kw["color"] = sum(w * np.asarray(p["color"], float) for w, p, _ in chosen) / total
        kw["metal"] = sum(w * np.asarray(p.get("metal", np.zeros(6)), float) for w, p, _ in chosen) / total
        if key[3] == S.FRESNEL_SCHLICK:  # a Principled metal's coat, (1 - Metallic) x its weight (Scene.mat_metal)
            kw["metal"][3:] = 1.0 - mass[key]
    else:
        kw["color"] = sum(w * np.asarray(p["color"], float) for w, p, _ in chosen)
    kw.pop("emission", None)
    # every part's emission shines whichever part the rest is taken as: a Principled part's, and an
    # Emission node's beside a BSDF taken as the surface
    glows = [(w, p) for w, p, _ in parts if kind != S.EMITTER and p["kind"] == S.EMITTER]
    emission = sum(w * np.asarray(p.get("emission", np.zeros(3)), float) for w, p, _ in parts) + \
        sum(w * np.asarray(p["color"], float) * float(p.get("strength", 1.0)) for w, p in glows)
    if np.max(emission) > 0:
        kw["emission"] = emission
    if "reflect_color" in first:
        kw["reflect_color"] = sum(w * np.asarray(p.get("reflect_color", p["color"]), float) for w, p, _ in chosen)
    if kind == S.DIFFUSE:
        lays = [_layer_of(p) for _, p, _ in chosen]
        heaviest = max(range(len(chosen)), key=lambda i: chosen[i][0])
        lay = lays[heaviest].copy()
        lay[3] = sum(w * la[3] for (w, _, _), la in zip(chosen, lays))
        kw["layer"] = tuple(lay)
        kw["textured"] = any(p.get("textured", False) for _, p, _ in chosen)
        if any(not np.allclose(np.delete(la, 3), np.delete(lays[heaviest], 3)) for la in lays):
            warn(f"material '{mat.name}': the diffuse parts of its shader mix are layered differently; "
                 f"the caustic on it is shaded as '{chosen[heaviest][2]}' is")
    dropped = [(w, name, f"{_PART_WORDS[p['kind']]}") for w, p, name in parts if _group_key(p) != key
               and not (kind != S.EMITTER and p["kind"] == S.EMITTER)]
    dropped += [(w, name, why) for w, name, why in left]
    if dropped:
        said = ", ".join(f"'{name}' (weight {w:.2f}, {why})" for w, name, why in dropped)
        warn(f"material '{mat.name}': its shader mix is taken as its {_PART_WORDS[kind]} part "
             f"(weight {mass[key]:.2f}); left out, neither casting nor receiving caustics: {said}")
    return kw


# mirrors and glass whose Normal may take a Bump node (bump.py)
_BUMPABLE = ("BSDF_GLASS", "BSDF_REFRACTION", "BSDF_GLOSSY", "BSDF_ANISOTROPIC", "BSDF_METALLIC")


def _bump_node(node):
    """The Bump node on a BSDF's Normal that the export bakes (bump.py): one Bump node whose Height
    is linked and whose Normal, Strength and Distance are not; None otherwise."""
    sock = node.inputs.get("Normal")
    src = _follow(sock) if sock is not None else None
    if src is None:
        return None
    b = src[0]
    if b.type != "BUMP" or b.mute or not _linked(b, "Height"):
        return None
    if any(_linked(b, name) for name in ("Normal", "Strength", "Distance")):
        return None
    return b


def _upstream(socket, limit=256):
    """The nodes feeding an input socket, through every link upstream (None past `limit` nodes)."""
    seen, todo = {}, [socket]
    while todo:
        src = _follow(todo.pop())
        if src is None or src[0].name in seen:
            continue
        seen[src[0].name] = src[0]
        if len(seen) > limit:
            return None
        todo.extend(src[0].inputs)
    return list(seen.values())


def _normal_source(node):
    """How the export bakes a mirror's or glass's driven Normal (bump.py): ("height", the Bump node)
    where it is one Bump node (its Height baked, the gradient taken by us: a bake's shading points have
    no ray differentials, so Cycles' own Bump would leave the normal unbent there); ("vector", None)
    where no Bump node lies upstream (a Normal Map, say: its output baked as it is); None otherwise
    (or where the Normal is not driven, or reads a node group or the mesh's attributes: _UNBAKED)."""
    b = _bump_node(node)
    if b is not None:
        nodes = _upstream(b.inputs["Height"])
        return None if nodes is None or any(n.type in _UNBAKED for n in nodes) else ("height", b)
    sock = node.inputs.get("Normal")
    if sock is None or _follow(sock) is None:
        return None
    nodes = _upstream(sock)
    if nodes is None or any(n.type in _UNBAKED + ("BUMP",) or n.mute for n in nodes):
        return None
    return "vector", None


# nodes whose value the copy of the mesh the export bakes on cannot give: a node group (what it
# holds is not read), the mesh's own attributes (the copy has only positions and the UV map)
_UNBAKED = ("GROUP", "ATTRIBUTE", "VERTEX_COLOR")


# where a Bump node's Height is read (Cycles, checked by renders of a sheet met from above and
# below): a texture coordinate of the position (Object, Camera, Window, Reflection, Normal, the
# Geometry node's Position) is offset in the frame of the flipped normal, so seen from behind the
# bump bends the other way; an attribute (Generated, UV, a UV Map or Attribute node, a texture's
# own default Vector) is offset with the surface, and the bump flips with it
_POSITION_COORDS = {("TEX_COORD", "Object"), ("TEX_COORD", "Camera"), ("TEX_COORD", "Window"),
                    ("TEX_COORD", "Reflection"), ("TEX_COORD", "Normal"), ("NEW_GEOMETRY", "Position"),
                    ("NEW_GEOMETRY", "Normal"), ("NEW_GEOMETRY", "True Normal"), ("NEW_GEOMETRY", "Incoming")}


def _bump_flips(tree, bump_node) -> bool:
    """Does Cycles' Bump node bend the normal with the surface when met from behind (the Height
    read through attributes only), or the other way (through the position: bump.bend's normals
    from behind)? Where both feed the Height, the position's way."""
    nodes = _upstream(bump_node.inputs["Height"]) or []
    names = {n.name for n in nodes}
    for lk in tree.links:
        if lk.is_valid and not lk.is_muted and lk.to_node.name in names | {bump_node.name} \
                and (lk.from_node.type, lk.from_socket.name) in _POSITION_COORDS:
            return False
    return True


def _bump_of(mat):
    """How a material whose surface is one mirror or glass BSDF with a driven Normal is baked:
    ("height", Bump node name, Distance (negated where the node inverts), Strength, whether the bump
    flips with the surface seen from behind: _bump_flips) or ("vector", BSDF node name, 0, 0, True);
    None where the export cannot bake it (see _normal_source)."""
    tree = mat.node_tree
    if tree is None or not _uses_nodes(mat):
        return None
    out = _output(tree, "OUTPUT_MATERIAL")
    src = _follow(out.inputs["Surface"]) if out is not None else None
    if src is None or src[0].mute or src[0].type not in _BUMPABLE + ("BSDF_PRINCIPLED",):
        return None
    how = _normal_source(src[0])
    if how is None:
        return None
    if how[0] == "vector":
        return "vector", src[0].name, 0.0, 0.0, True
    b = how[1]
    dist = float(b.inputs["Distance"].default_value)
    return ("height", b.name, -dist if b.invert else dist, float(b.inputs["Strength"].default_value),
            _bump_flips(tree, b))


def _thin_film(node) -> list:
    """['thin film'] where a node's Thin Film Thickness is linked or above Cycles' cutoff (0.1 nm,
    THINFILM_THICKNESS_CUTOFF, compared in float32 as Cycles does)."""
    sock = node.inputs.get("Thin Film Thickness")
    if sock is not None and (_follow(sock) is not None or np.float32(sock.default_value) > np.float32(thinfilm.CUTOFF)):
        return ["thin film"]
    return []



def _film(node, mat, warn) -> tuple:
    """A node's thin film as Scene.mat_film holds it: (Thin Film Thickness in nm, Thin Film IOR), S.NO_FILM
    where it is Cycles' cutoff thin or less. A thickness or index driven by nodes is not read (warned
    about): no film."""
    sock = node.inputs.get("Thin Film Thickness")
    if not _thin_film(node):
        return S.NO_FILM
    if _follow(sock) is not None or _linked(node, "Thin Film IOR"):
        warn(f"material '{mat.name}': the thin film of '{node.name}' is driven by nodes (a textured thickness or "
             f"index): its iridescence is not baked")
        return S.NO_FILM
    return float(sock.default_value), max(float(node.inputs["Thin Film IOR"].default_value), 1e-5)


def _anisotropy(node, name, roughness) -> list:
    """['anisotropy'] where a rough node's anisotropy input is linked or not 0 (a perfect mirror has
    none to show)."""
    sock = node.inputs.get(name)
    if sock is None or not (_follow(sock) is not None or float(sock.default_value) != 0.0):
        return []
    rough = node.inputs.get("Roughness")
    return ["anisotropy"] if (rough is not None and _follow(rough) is not None) or float(roughness) > 0 else []


def _metallic(node, mat, warn) -> dict:
    """The Metallic BSDF (Blender 4.3 on): Cycles' F82-Tint metal (Base Color, Edge Tint) or a physical
    conductor (IOR n and Extinction k per channel), the roughness and distribution of a Glossy BSDF."""
    r = _const(node, "Roughness")
    film = _film(node, mat, warn)
    ignored = _anisotropy(node, "Anisotropy", r)
    if ignored:
        warn(f"material '{mat.name}': the {' and '.join(ignored)} of Metallic BSDF '{node.name}' ignored")
    if getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
        n = np.maximum(_const(node, "IOR"), 0.0)
        k = np.maximum(_const(node, "Extinction"), 0.0)
        if not np.any(np.concatenate([n, k]) > 0):
            raise _Unsupported(f"Metallic BSDF '{node.name}' has IOR and Extinction 0 (no conductor)")
        return dict(kind=S.CONDUCTOR, color=conductor_f0(n, k), roughness=r, fresnel=S.FRESNEL_CONDUCTOR,
                    reflect_color=np.ones(3), ior=1.0, metal=np.concatenate([n, k]),
                    distribution=_distribution(node, mat, warn, r), film=film)
    f0 = np.clip(_const(node, "Base Color"), 0.0, 1.0)
    tint = np.clip(_const(node, "Edge Tint"), 0.0, 1.0)
    return dict(kind=S.CONDUCTOR, color=f0, roughness=r, fresnel=S.FRESNEL_SCHLICK, reflect_color=np.ones(3),
                ior=1.0, metal=f82_tint_metal(f0, tint), distribution=_distribution(node, mat, warn, r), film=film)


def _bsdf(node, mat, warn, direct=False) -> dict:
    """Material keywords for one BSDF node (raises _Unsupported for a node we cannot represent);
    direct: the node is the material's surface (no mix), where a Bump node on its Normal is ours."""
    if node.mute:
        raise _Unsupported(f"node '{node.name}' is muted")
    t = node.type
    if t == "BSDF_PRINCIPLED":
        base, textured = _colour(node, "Base Color")
        metallic = _const(node, "Metallic")
        rough = _const(node, "Roughness")
        trans = _const(node, "Transmission Weight")
        ior = _const(node, "IOR")
        ignored = []

        def active(sock_name, nonzero=lambda v: float(v) > 0):
            sock = node.inputs.get(sock_name)
            return sock is not None and (_follow(sock) is not None or nonzero(sock.default_value))

        emission = np.zeros(3)
        if active("Emission Strength") and active("Emission Color", lambda c: max(c[:3]) > 0):
            # a mesh light of radiance Emission Color x Strength (builder); Cycles puts the emission
            # under the coat and the sheen, which take an angle-dependent share of it
            textured_glow = _linked(node, "Emission Color") or _linked(node, "Emission Strength")
            if textured_glow or active("Coat Weight") or active("Sheen Weight"):
                ignored.append("emission (textured)" if textured_glow else "emission (under a coat or sheen)")
            else:
                emission = _const(node, "Emission Color")[:3] * float(_const(node, "Emission Strength"))
        receiver = metallic < 0.5 and trans < 0.5
        coat_w = 0.0
        if active("Coat Weight"):
            # over a diffuse receiver the clear coat takes its share towards the eye (layer.py);
            # its tint's absorption, its own normal, and a coat over metal or glass are not ours
            tint_c = _input(node, "Coat Tint", np.ones(3))
            if receiver and np.allclose(tint_c, 1.0) and not _linked(node, "Coat Normal"):
                coat_w = float(min(_const(node, "Coat Weight"), 1.0))
            else:
                ignored.append("coat")
        for sock_name, label in (("Sheen Weight", "sheen"), ("Subsurface Weight", "subsurface")):
            if active(sock_name):
                ignored.append(label)
        # a thin film: over a metal's or a glass's Fresnel (and the metal's coat), baked; over a diffuse's
        # coat, Cycles' share of the diffuse under it (the coat's reflectance with the film) is not ours
        film = _film(node, mat, warn)
        if film[0] > 0 and not (metallic >= 0.5 or trans >= 0.5):
            ignored.append("thin film (over a diffuse)")
        ignored += _anisotropy(node, "Anisotropic", rough)
        # a metal's Specular Tint is its edge's tint (F82-Tint); a textured one is left white
        try:
            edge_tint = np.minimum(_input(node, "Specular Tint", np.ones(3)), 1.0)
        except _Unsupported:
            edge_tint = np.ones(3)
            if metallic >= 0.5:
                ignored.append("specular tint (textured)")
        a = node.inputs.get("Alpha")
        if a is not None and (_follow(a) is not None or float(a.default_value) < 1.0):
            ignored.append("alpha")
        # a receiver's bump: read from the view where the camera sees it (_view_maps); a mirror's
        # or glass's: baked (bump.py)
        if _linked(node, "Normal") and not (direct and (receiver or _normal_source(node) is not None)):
            ignored.append("normal map")
        if ignored:
            warn(f"material '{mat.name}': Principled BSDF {', '.join(ignored)} ignored")
        if textured and (metallic >= 0.5 or trans >= 0.5):
            raise _Unsupported("a textured Base Color is supported on diffuse surfaces only")
        if textured:
            _say_textured(mat, base, warn)
        # Cycles weighs the metal lobe by Metallic and the glass by (1 - Metallic) x Transmission;
        # a material is the lobe that weighs most, the rest of it is left out (and said so)
        if metallic >= 0.5:
            # the rest is a dielectric coat (a mirror at Roughness 0: it casts) over a diffuse
            level = _input(node, "Specular IOR Level", 0.5)
            eta, _ = principled_layer(ior, level, np.ones(3))
            if metallic < 1.0:
                warn(f"material '{mat.name}': Principled BSDF Metallic {metallic:g}: the diffuse under "
                     f"its coat ({1 - metallic:.0%} of it) receives no caustics")
            # Cycles' metal lobe: F82-Tint from F0 = the Base Color, its Specular Tint the edge's tint
            f0 = np.clip(base, 0.0, 1.0)
            return dict(kind=S.CONDUCTOR, color=f0, roughness=rough, fresnel=S.FRESNEL_SCHLICK,
                        reflect_color=np.full(3, float(metallic)), ior=eta if eta > 1.0 else 1.0,
                        distribution=_distribution(node, mat, warn, rough), emission=emission,
                        metal=f82_tint_metal(f0, edge_tint), film=film)
        if trans >= 0.5:
            w_glass = float((1.0 - metallic) * trans)
            if w_glass < 1.0:
                warn(f"material '{mat.name}': Principled BSDF glass of weight {w_glass:.2f} ((1 - Metallic) x "
                     f"Transmission); the rest neither casts nor receives caustics")
            # Cycles' Principled glass tints transmission by sqrt(base colour) at every
            # refraction and leaves reflection white; its Specular Tint scales the Fresnel term's
            # value at normal incidence (Scene.mat_metal[:3] = tint - 1; optics.tinted_glass)
            try:
                spec_tint = np.maximum(_input(node, "Specular Tint", np.ones(3)), 0.0)
            except _Unsupported:
                spec_tint = np.ones(3)
                warn(f"material '{mat.name}': Principled BSDF Specular Tint driven by nodes (textured) on glass "
                     f"ignored")
            return dict(kind=S.DIELECTRIC, color=np.sqrt(np.clip(base, 0.0, 1.0)) * w_glass,
                        reflect_color=np.full(3, w_glass), ior=ior, roughness=rough,
                        distribution=_distribution(node, mat, warn, rough), emission=emission, film=film,
                        metal=np.concatenate([spec_tint - 1.0, np.zeros(3)]))
        # the diffuse under Cycles' layers: what metallic and transmission leave, beneath a
        # dielectric glossy layer that takes its share towards the eye (layer.py)
        level = _input(node, "Specular IOR Level", 0.5)
        tint = _input(node, "Specular Tint", np.ones(3))
        eta, tint_max = principled_layer(ior, level, tint)
        # Cycles' Oren-Nayar from a Diffuse Roughness of 1e-5 (CLOSURE_WEIGHT_CUTOFF)
        sigma = _input(node, "Diffuse Roughness", 0.0)
        sigma = float(min(sigma, 1.0)) if sigma >= 1e-5 else 0.0
        coat_ior = float(_input(node, "Coat IOR", 1.5))
        coat_rough = float(_input(node, "Coat Roughness", 0.03))
        return dict(kind=S.DIFFUSE, color=base * (1.0 - metallic) * (1.0 - trans), roughness=rough,
                    layer=(eta, float(rough), tint_max, (1.0 - metallic) * (1.0 - trans), sigma, coat_w,
                           coat_ior, coat_rough), textured=textured, view_bump=direct and _linked(node, "Normal"),
                    emission=emission)
    if t in _BUMPABLE and _linked(node, "Normal") and not (direct and _normal_source(node) is not None):
        warn(f"material '{mat.name}': the Normal of '{node.name}' is driven by nodes the export cannot bake "
             f"(a Bump node below another node, a node group, a mesh attribute, a bump inside a shader mix): its "
             f"caustic is baked from the unbumped surface, where Cycles' follows the bumps")
    if t == "BSDF_METALLIC":
        return _metallic(node, mat, warn)
    if t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC") and _thin_film(node):
        warn(f"material '{mat.name}': the thin film of '{node.name}' ignored")
    if t == "BSDF_GLASS":
        c = _const(node, "Color")
        r = _const(node, "Roughness")
        return dict(kind=S.DIELECTRIC, color=c, reflect_color=c.copy(), ior=_const(node, "IOR"), roughness=r,
                    distribution=_distribution(node, mat, warn, r), film=_film(node, mat, warn))
    if t == "BSDF_REFRACTION":  # Cycles: transmits Color, no Fresnel term, no reflection
        r = _const(node, "Roughness")
        return dict(kind=S.DIELECTRIC, color=_const(node, "Color"), reflect_color=np.zeros(3),
                    ior=_const(node, "IOR"), roughness=r, fresnel=S.REFRACTION_ONLY,
                    distribution=_distribution(node, mat, warn, r))
    if t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
        if node.inputs.get("Anisotropy") is not None and (
                _linked(node, "Anisotropy") or float(node.inputs["Anisotropy"].default_value) != 0):
            warn(f"material '{mat.name}': Glossy BSDF anisotropy ignored")
        r = _const(node, "Roughness")
        return dict(kind=S.CONDUCTOR, color=_const(node, "Color"), roughness=r, fresnel=S.FRESNEL_NONE,
                    distribution=_distribution(node, mat, warn, r))
    if t == "BSDF_DIFFUSE":  # Cycles' Oren-Nayar from a Roughness of 1e-5
        sigma = float(_const(node, "Roughness"))
        color, textured = _colour(node, "Color")
        if textured:
            _say_textured(mat, color, warn)
        if _linked(node, "Normal") and not direct:
            warn(f"material '{mat.name}': the Normal of '{node.name}' is driven by a node (a bump or normal map) "
                 f"inside a shader mix: the caustic on it is shaded with the unbumped normal, where Cycles' follows "
                 f"the bumps")
        return dict(kind=S.DIFFUSE, color=color, roughness=sigma, textured=textured,
                    layer=(0.0, 0.0, 0.0, 1.0, min(sigma, 1.0) if sigma >= 1e-5 else 0.0, 0.0, 0.0, 0.0),
                    view_bump=direct and _linked(node, "Normal"))
    if t == "EMISSION":
        return dict(kind=S.EMITTER, color=_const(node, "Color"),
                    strength=_const(node, "Strength"))
    raise _Unsupported(f"node '{node.name}' is not supported")


_RAYS = (("visible_camera", "camera", S.RAY_CAMERA), ("visible_diffuse", "diffuse", S.RAY_DIFFUSE),
         ("visible_glossy", "glossy", S.RAY_GLOSSY), ("visible_transmission", "transmission", S.RAY_TRANSMISSION),
         ("visible_shadow", "shadow", S.RAY_SHADOW))


def _ray_visibility(ob, prefix="visible_") -> int:
    """An object's or a light's Ray Visibility (Object > Visibility) as S.RAY_* bits (prefix "": the
    world's, World > Settings; a setting it lacks counts as on)."""
    return sum(bit for attr, _, bit in _RAYS if getattr(ob, prefix + attr.removeprefix("visible_"), True))


def _link_states(collection, state=None, out=None) -> dict:
    """The objects of a Light Linking collection, each with its Include / Exclude state, as Blender
    resolves them (its depsgraph's light linking cache): an object inside a child collection takes
    that child's state (the first level's, however deep it lies), the collection's own objects theirs;
    the later one counts where an object is met twice (children first, then objects). Keys: original
    objects (an instance is its object's)."""
    out = {} if out is None else out
    for child, link in zip(collection.children, collection.collection_children):
        _link_states(child, link.light_linking.link_state if state is None else state, out)
    for ob, link in zip(collection.objects, collection.collection_objects):
        out[ob.original if getattr(ob, "original", None) is not None else ob] = \
            link.light_linking.link_state if state is None else state
    return out


def _linked_objects(ob, which="receiver_collection"):
    """The original objects emitter ob (a light's or an emissive mesh's object) lights by its Light
    Linking's receiver collection (which="blocker_collection": that shadow it, Shadow Linking), as a
    predicate on an original object; None: every object (no collection). Blender, for both: an object
    set to Include is in; once any is, only those; else every object but those set to Exclude."""
    c = getattr(getattr(ob, "light_linking", None), which, None)
    if c is None:
        return None
    states = _link_states(c)
    if any(v == "INCLUDE" for v in states.values()):
        return lambda o: states.get(o) == "INCLUDE"
    return lambda o: states.get(o) != "EXCLUDE"


def _say_visibility(ob, warn):
    """Warn about an object's Cycles settings the layer does not read: a holdout, a shadow catcher (the
    layer's caustic on it is added to the render like any receiver's). (Its Ray Visibility is read:
    _ray_visibility.)"""
    if getattr(ob, "is_holdout", False):
        warn(f"object '{ob.name}': a holdout; the layer treats it as its material says")
    if getattr(ob, "is_shadow_catcher", False):
        warn(f"object '{ob.name}': a shadow catcher; the caustic on it is composited like any receiver's, "
             f"not into Cycles' shadow catcher pass")


# ------------------------------------------------------------------------------ meshes
def _mesh_arrays(ob_eval):
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


def _to_world(local, M):
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


# ------------------------------------------------------------------------------ bumps
def _area(verts, M) -> float:
    """The world surface area of local triangles (T, 3, 3) under matrix M."""
    v = verts @ np.asarray(M, float)[:3, :3].T
    return float(0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1).sum())


def _bumped(local, specs, source, target, warn):
    """A mesh's arrays with its bumped mirrors and glass (specs: builder material id -> _bump_of's
    (kind, node name, Distance, Strength, flips) and the Material) cut into about `target` triangles,
    Cycles' values baked at every vertex (bump.py): a Bump node's Height (the normals bent in _to_world,
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
            heights = _bake_normals(source, co, tv, slot, uvs, local["uv_name"], "height")
            if not np.all(np.isfinite(heights)):
                warn(f"object '{source['name']}': its Bump node's Height is not finite everywhere; taken as 0 there")
                heights = np.nan_to_num(heights, nan=0.0, posinf=0.0, neginf=0.0)
            out["bump"] = dict(heights=heights, distance=dist[parent], flips=flips[parent],
                               strength=np.where(kind == 1, strength[parent], 0.0))
        if (kind == 2).any():
            world = _bake_normals(source, co, tv, slot, uvs, local["uv_name"], "vector")
            # to the object's space, where _to_world takes every instance's normals from
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


def _emission_bake():
    """Cycles' Emission bake of the context's active object to its active colour attribute."""
    return bpy.ops.object.bake(type="EMIT", target="VERTEX_COLORS")


def _bake_normals(source, co, tv, slot, uvs, uv_name, kind) -> np.ndarray:
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
            driver = _follow(tree.nodes[node_name].inputs["Height" if kind == "height" else "Normal"])[1]
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


# ------------------------------------------------------------------------------ a bumped receiver's view
VIEW_SUBPIXELS = 2_000_000  # the view maps' sub-pixels at most (two float32 maps of 24 MB)
VIEW_MOST = 4  # sub-pixels per pixel side at most


def _view_render(sc):
    """Cycles' render of scene sc to its render.filepath."""
    bpy.ops.render.render(write_still=True, scene=sc.name)


def _view_maps(bpy_scene, objects, camera, warn):
    """What Cycles' camera rays meet first on the bumped receivers `objects` alone, through the
    centres of s x s sub-pixels of the frame (Scene.view_normals, view_points: its Normal and
    Position passes, a sample per sub-pixel, no bounces, a pixel filter of 0.01): the shading normals
    a bump or normal map bends, as Cycles' own nodes make them, whatever drives them, where nothing
    else hides them (a floor under water, seen through it, is looked up where it projects:
    eye.view_bumped). s is the most (up to VIEW_MOST) that keeps VIEW_SUBPIXELS. A scene of its own
    holds the objects (shared, not copied) and the camera, at the scene's frame; it, its files and a
    Render Result image it made are removed again, the user's scene is not touched. None, said, where
    Cycles cannot render it."""
    import tempfile
    from pathlib import Path

    from ..io.exr import read_passes

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
            r.engine = "CYCLES"
            r.resolution_x, r.resolution_y, r.resolution_percentage = W * s, H * s, 100
            r.pixel_aspect_x, r.pixel_aspect_y = ur.pixel_aspect_x, ur.pixel_aspect_y
            r.use_border = False
            r.use_motion_blur = False
            r.use_compositing = r.use_sequencer = False
            r.image_settings.media_type = "MULTI_LAYER_IMAGE"
            r.image_settings.color_depth = "32"
            r.filepath = str(Path(tmp) / "view.exr")
            c = sc.cycles
            c.device = "CPU"
            c.samples, c.seed, c.use_animated_seed = 1, 0, False
            c.use_adaptive_sampling = c.use_denoising = False
            c.max_bounces = 0
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


# ------------------------------------------------------------------------------ lights
def _light_node_factor(light, warn):
    """Colour factor from a light's node tree (Emission node) if it uses nodes."""
    if not getattr(light, "use_nodes", False) or light.node_tree is None:  # not deprecated
        return np.ones(3)
    try:
        node = _shader_node(light.node_tree, "OUTPUT_LIGHT")
        if node is None:
            return np.zeros(3)
        if node.type != "EMISSION":
            raise _Unsupported(f"node '{node.name}' is not supported")
        return _const(node, "Color") * _const(node, "Strength")
    except _Unsupported as e:
        warn(f"light '{light.name}': {e}; its node tree is ignored")
        return np.ones(3)


def _export_light(b, name, ob, M, warn):
    lt = ob.data
    orig = lt.original if getattr(lt, "original", None) is not None else lt
    color = np.array(lt.color[:3], float)
    if getattr(lt, "use_temperature", False):
        color = color * np.array(lt.temperature_color[:3], float)
    power = float(lt.energy) * 2.0 ** float(getattr(lt, "exposure", 0.0))
    color = color * _light_node_factor(lt, warn)
    normalize = bool(getattr(lt, "normalize", True))
    caustics = bool(orig.cycles.is_caustics_light)
    Mn = _orthonormal(M)
    sc = _axis_scale(M)
    kw = dict(matrix=Mn, color=color, caustics=caustics)
    if lt.type in ("POINT", "SPOT"):
        r = float(lt.shadow_soft_size)
        if not normalize:  # Cycles divides by the sphere area (4 if r = 0) only when normalised
            power *= 4.0 * math.pi * r * r if r > 0 else 4.0
        kw.update(radius=r, soft_falloff=bool(lt.use_soft_falloff))
        if lt.type == "SPOT":
            kw.update(spot_size=float(lt.spot_size), spot_blend=float(lt.spot_blend))
            if abs(sc[0] - sc[1]) > 1e-6 * max(sc[0], sc[1]):
                warn(f"light '{name}': non-uniform scale of a spot cone is ignored")
    elif lt.type == "AREA":
        shape = lt.shape
        sx = float(lt.size)
        sy = float(lt.size_y) if shape in ("RECTANGLE", "ELLIPSE") else sx
        sx, sy = sx * sc[0], sy * sc[1]
        if abs(sx - sy) > 1e-6 * max(sx, sy):  # unequal scale: Cycles stretches the shape
            shape = {"SQUARE": "RECTANGLE", "DISK": "ELLIPSE"}.get(shape, shape)
        else:
            sy = sx if shape in ("SQUARE", "DISK") else sy
        if not normalize:
            power *= sx * sy * (math.pi / 4 if shape in ("DISK", "ELLIPSE") else 1.0)
        kw.update(shape=shape, size=(sx, sy), spread=float(lt.spread))
        if getattr(orig.cycles, "is_portal", False):
            warn(f"light '{name}': portal lights are skipped")
            return
    elif lt.type == "SUN":
        ang = float(lt.angle)
        if not normalize:
            power *= math.pi * math.sin(ang / 2) ** 2 if ang > 0 else 1.0
        kw.update(angle=ang)
    else:
        warn(f"light '{name}': type {lt.type} is not supported; skipped")
        return
    # a light's Ray Visibility (its object's): which rays leaving a mirror or glass (or a diffuse
    # surface, for light that bounces before it meets a caster) see it; camera and shadow rays are in no
    # caustic path of the layer's (the bits stay on)
    b.light(name, lt.type, power=power, visibility=_ray_visibility(ob) & S.PATH_RAYS | S.RAY_CAMERA | S.RAY_SHADOW,
            **kw)


# ------------------------------------------------------------------------------ camera
def _export_camera(bpy_scene, depsgraph, warn) -> S.Camera:
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
        matrix_world=_orthonormal(np.array(ev.matrix_world)),
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


# ------------------------------------------------------------------------------- world
def _world(bpy_scene, warn, pixels=True):
    """The world as the layer sees it: (colour x strength, map, rotation). A constant Background
    gives its colour and no map; an Environment Texture (equirectangular) on its Color, fed the
    view direction or that direction through a Mapping node that turns it, gives the strength
    (as a colour), the image's linear pixels and the turn (Scene.world_map). Anything else is
    black, warned. pixels False: the map is not read (None), only whether it can be."""
    w = bpy_scene.world
    if w is None:
        return np.zeros(3), None, None
    if w.node_tree is None or not _uses_nodes(w):
        return np.array(w.color[:3], float), None, None
    try:
        node = _shader_node(w.node_tree, "OUTPUT_WORLD")
        if node is None:
            return np.zeros(3), None, None
        if node.type != "BACKGROUND":
            raise _Unsupported(f"node '{node.name}' is not supported")
        strength = _const(node, "Strength")
        src = _follow(node.inputs["Color"])
        if src is None or src[0].type != "TEX_ENVIRONMENT":
            return _const(node, "Color") * strength, None, None
        image, rotation = _environment(src[0], pixels, lambda message: warn(f"world '{w.name}': {message}"))
        return np.full(3, float(strength)), image, rotation
    except _Unsupported as e:
        warn(f"world '{w.name}': {e}; world lighting treated as black")
        return np.zeros(3), None, None


def world_unread(bpy_scene):
    """The name of the scene's world when its node setup is one the layer cannot read (a Sky
    Texture, a node trick: black to the layer, with a warning at export), else None."""
    said = []
    _world(bpy_scene, said.append, pixels=False)
    return bpy_scene.world.name if said else None


def _environment(tex, pixels=True, warn=lambda message: None):
    """(linear pixels (H, W, 3) float32, rotation (3, 3)) of an Environment Texture node, its
    Vector the view direction or that direction through a Mapping node. Cycles looks the map up
    at R (S d) for a Mapping of type Point (no Location), Vector or Normal, at S^-1 R^-1 d for one
    of type Texture, and the lookup does not depend on the length: a uniform S drops out."""
    if tex.projection != "EQUIRECTANGULAR":
        raise _Unsupported(f"node '{tex.name}': its {tex.projection.lower().replace('_', ' ')} projection is not "
                           "supported")
    rotation = np.eye(3)
    src = _follow(tex.inputs["Vector"])
    if src is not None:
        mp = src[0]
        if mp.type != "MAPPING":
            raise _Unsupported(f"node '{mp.name}' on the Environment Texture's Vector is not supported")
        for name in ("Location", "Rotation", "Scale"):
            if name in mp.inputs and _linked(mp, name):
                raise _Unsupported(f"node '{mp.name}': a linked {name} is not supported")
        scale = np.array(mp.inputs["Scale"].default_value[:], float) if "Scale" in mp.inputs else np.ones(3)
        loc = np.array(mp.inputs["Location"].default_value[:], float) if "Location" in mp.inputs else np.zeros(3)
        if not (np.allclose(scale, scale[0]) and scale[0] > 0) or (mp.vector_type in ("POINT", "TEXTURE")
                                                                   and np.any(loc != 0)):
            raise _Unsupported(f"node '{mp.name}': only a turn (no Location, the same positive Scale on every "
                               "axis) is supported")
        inner = _follow(mp.inputs["Vector"])
        if inner is not None and not (inner[0].type == "TEX_COORD" and inner[1].name == "Generated"):
            raise _Unsupported(f"node '{inner[0].name}' on the Mapping's Vector is not supported")
        if "Rotation" in mp.inputs:
            rotation = np.array(mp.inputs["Rotation"].default_value.to_matrix(), float)  # Euler XYZ
        if mp.vector_type == "TEXTURE":
            rotation = rotation.T
    image = _image_linear(tex.image, MAX_WORLD_PIXELS, pixels)
    if image is None:
        raise _Unsupported(f"node '{tex.name}': its image is missing or larger than {MAX_WORLD_PIXELS} pixels")
    if not pixels:
        return None, rotation
    bad = ~(np.isfinite(image) & (image >= 0))
    if bad.any():  # an HDRI's processing can leave a few (a colour space's conversion)
        image = np.where(bad, np.float32(0.0), image)
        warn(f"image '{tex.image.name}': {int(bad.any(axis=2).sum())} pixels negative or not a number, taken as "
             "black")
    return _averaged_down(image, WORLD_MAP_WIDTH), rotation


MAX_WORLD_PIXELS = 8192 * 4096  # an 8K HDRI: read once (0.5 GB for a moment), then averaged down
WORLD_MAP_WIDTH = 2048  # the layer's map of the world is at most this wide (a sun of 0.5 deg: 3 pixels)


def _averaged_down(image, width):
    """An equirectangular map averaged over blocks to at most `width` pixels across (and the
    height in proportion): the same light, in as many pixels as a caustic needs."""
    h, w = image.shape[:2]
    if w <= width:
        return image
    cols = np.linspace(0, w, width + 1).round().astype(np.int64)
    rows = np.linspace(0, h, max(1, round(h * width / w)) + 1).round().astype(np.int64)
    summed = np.add.reduceat(np.add.reduceat(image.astype(np.float64), rows[:-1], axis=0), cols[:-1], axis=1)
    return (summed / np.outer(np.diff(rows), np.diff(cols))[..., None]).astype(np.float32)


def _world_visibility(w) -> int:
    """The rays that see the world (World > Settings > Ray Visibility) as S.RAY_* bits: a caustic's
    last segment is a ray leaving a mirror (glossy) or glass (transmission); seen by neither, the world
    lights no caustic (Cycles' does not either)."""
    vis = getattr(w, "cycles_visibility", None)
    return S.RAY_ALL if vis is None else _ray_visibility(vis, prefix="") | S.RAY_SHADOW


# ------------------------------------------------------------------------------ export
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
    camera = _export_camera(bpy_scene, depsgraph, _warn)

    b = SceneBuilder(bpy_scene.name)
    b.camera = camera
    world, world_map, rotation = _world(bpy_scene, _warn)
    b.world_color = world
    lit = world.max() > 0 and (world_map is None or world_map.max() > 0)
    if lit and _world_visibility(bpy_scene.world) & (S.RAY_GLOSSY | S.RAY_TRANSMISSION):
        # a light of the layer's: its light through mirrors and glass is a caustic too
        w = bpy_scene.world
        b.world(world, name=w.name, caustics=bool(getattr(w.cycles, "is_caustics_light", False)),
                image=world_map, rotation=rotation, visibility=_world_visibility(w))
    c = getattr(bpy_scene, "cycles", None)
    if c is not None:  # Light Paths > Max Bounces, as Cycles renders with them (bounces.py)
        b.light_paths = np.array([c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces],
                                 np.int64)

    mat_index = {}  # material name_full -> builder index

    def material_id(mat):
        if mat is None:
            key = DEFAULT_MATERIAL
            if key not in mat_index:
                mat_index[key] = b.material(key, S.DIFFUSE, color=(DEFAULT_ALBEDO,) * 3)
            return mat_index[key]
        key = mat.original.name_full if getattr(mat, "original", None) is not None else mat.name_full
        if key not in mat_index:
            # Cycles' Bump Map Correction (on by default) also bends smooth-shaded mirrors' and
            # glass's shading normals at grazing angles (optics.valid_reflection1)
            corr = bool(getattr(getattr(mat, "cycles", None), "use_bump_map_correction", True))
            kw = classify_material(mat, _warn)
            mat_index[key] = b.material(key, **kw, bump_correction=corr)
            spec = _bump_of(mat) if kw["kind"] in (S.DIELECTRIC, S.CONDUCTOR) else None
            if spec is not None:
                orig_mat = mat.original if getattr(mat, "original", None) is not None else mat
                bump_specs[mat_index[key]] = spec + (orig_mat,)
        return mat_index[key]

    bump_specs = {}  # builder material id -> (kind, node name, Distance, Strength, flips, bpy Material) (_bump_of)

    mesh_cache = {}
    meshes = []  # (name, mesh_cache key, matrix, caster, receiver, Ray Visibility, original object) in order
    emitters = []  # (the builder's light entry, its original object): their Light Linking, once every mesh is known
    view_objects = {}  # each mesh's object (or its instancer), in order, by its key: what the view may hold
    names_used = {}
    viewport = getattr(depsgraph, "mode", "VIEWPORT") == "VIEWPORT"
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
        if ob.type == "LIGHT":
            n_lights = len(b.lights)
            _export_light(b, name, ob, M, _warn)
            if len(b.lights) > n_lights:
                emitters.append((b.lights[-1], orig))
            continue

        key = (orig.name_full, ob.data.as_pointer() if ob.data is not None else 0)
        if key not in mesh_cache:
            if viewport and not inst.is_instance:
                for mod in orig.modifiers:
                    lv, rl = getattr(mod, "levels", None), getattr(mod, "render_levels", None)
                    if mod.show_viewport and lv is not None and rl is not None and lv != rl:
                        _warn(f"object '{orig.name}': modifier '{mod.name}' is exported at its "
                              f"viewport level {lv}, not its render level {rl}")
            local = _mesh_arrays(ob)
            if local is not None:
                slots = [s.material for s in ob.material_slots] or local["mesh_materials"]
                # no slots: default diffuse; an empty slot: default diffuse; an index past
                # the last slot uses the last slot (as Blender does)
                ids = np.array([material_id(m) for m in slots] or [material_id(None)], np.int32)
                local["mat_index"] = np.clip(local["mat_index"], 0, len(ids) - 1)
                tri_mat = ids[local["mat_index"]]
                local["tri_material"] = tri_mat.astype(np.int32)
                if any(int(m) in bump_specs for m in np.unique(tri_mat)):
                    local["bump_source"] = dict(
                        name=orig.name, matrix=M, texspace=(tuple(ob.data.texspace_location),
                                                            tuple(ob.data.texspace_size)),
                        slots=[bump_specs.get(int(m)) for m in ids])
            mesh_cache[key] = local
        local = mesh_cache[key]
        if local is None:
            continue
        if k == 0 and not inst.is_instance:
            _say_visibility(orig, _warn)
        view_objects.setdefault(key, {})[inst.parent.original if inst.is_instance and inst.parent is not None
                                        else orig] = None
        visibility = _ray_visibility(orig)
        if inst.is_instance and inst.parent is not None:  # Cycles: an instance inherits what its instancer hides
            visibility &= _ray_visibility(inst.parent.original)
        meshes.append((name, key, M, bool(orig.cycles.is_caustics_caster), bool(orig.cycles.is_caustics_receiver),
                       visibility, orig))
    # bumps are baked once the depsgraph's instances are read (the bake adds a scene of its own)
    bumped = [key for key, local in mesh_cache.items() if local is not None and "bump_source" in local]
    areas = [_area(mesh_cache[key]["verts"], mesh_cache[key]["bump_source"]["matrix"]) for key in bumped]
    for key, target in zip(bumped, bump.targets(areas)):
        local = mesh_cache[key]
        source = local.pop("bump_source")
        specs = {int(m): bump_specs[int(m)] for m in np.unique(local["tri_material"]) if int(m) in bump_specs}
        mesh_cache[key] = _bumped(local, specs, source, int(target), _warn)
    # Light and Shadow Linking (the receiver and blocker collections of lights and of emissive meshes):
    # the objects each lights, and those that shadow it
    names_of = {}
    for name, key, M, caster, receiver, visibility, orig in meshes:
        names_of.setdefault(orig, []).append(name)

    memo = {}  # (original, which) -> its names: an emitter's instances share them

    def linked(emitter, which="receiver_collection"):
        if (emitter, which) not in memo:
            member = _linked_objects(emitter, which)
            memo[emitter, which] = None if member is None else \
                [nm for o, names in names_of.items() if member(o) for nm in names]
        return memo[emitter, which]

    for entry, orig in emitters:
        entry["lit"], entry["blockers"] = linked(orig), linked(orig, "blocker_collection")
    view_bumped = {}  # the objects with a bumped diffuse (a receiver, by the plan's rules): the view holds them alone
    for name, key, M, caster, receiver, visibility, orig in meshes:
        local = mesh_cache[key]
        v, n, uv, back = _to_world(local, M)
        b.mesh_corners(name, v, n, uv, local["tri_material"], caster=caster, receiver=receiver,
                       smooth=bool(local["smooth"].any()), tri_normals_back=back, visibility=visibility,
                       lit=linked(orig), blockers=linked(orig, "blocker_collection"))
        if any(b.materials[int(m)]["view_bump"] for m in np.unique(local["tri_material"])):
            view_bumped.update(view_objects[key])
    maps = None
    if view_bumped:
        maps = _view_maps(bpy_scene, list(view_bumped), camera, _warn)
        if maps is not None:
            b.view_normals, b.view_points = maps
    if maps is None:
        for m in b.materials:
            m["view_bump"] = False
    return b.build()
