"""A bpy Material -> ``SceneBuilder.material`` keywords (``classify_material``): its surface (one BSDF
node: bsdfs.py; a Mix or Add Shader's closures: the group of parts that weighs most, colours summed
by weight), a glass's Volume Absorption, warnings for what is left out and a stated fallback (a
diffuse of albedo 0.8) for what cannot be represented; and ``MaterialTable``, the builder's ids of a
scene's materials, each classified once."""
from __future__ import annotations

import numpy as np

from ..scene import arrays as S
from ..shading.microfacet import MULTI_GGX
from .bsdfs import DEFAULT_ALBEDO, bsdf
from .bump_nodes import bump_of
from .nodes import Unsupported, constant, follow, is_linked, output_node, uses_nodes

DEFAULT_MATERIAL = "<default diffuse>"


def classify_material(mat, warn) -> dict:
    """Keyword arguments for ``SceneBuilder.material`` (minus the name) for a bpy Material: its
    surface, and a glass's Volume Absorption."""
    kw = _surface_material(mat, warn)
    tree = mat.node_tree
    out = output_node(tree, "OUTPUT_MATERIAL") if tree is not None and uses_nodes(mat) else None
    if kw["kind"] in (S.DIELECTRIC, S.CONDUCTOR) and out is not None and is_linked(out, "Displacement"):
        warn(f"material '{mat.name}': its Displacement is linked: its caustic is baked from the undisplaced "
             f"surface, where Cycles' follows the bumps (the mesh's own shape, modifiers included, is used)")
    vol = follow(out.inputs["Volume"]) if out is not None and out.inputs.get("Volume") is not None else None
    if vol is None or vol[0].mute:
        return kw
    node, why = vol[0], None
    if kw["kind"] != S.DIELECTRIC:
        why = "only a glass's volume is ours"
    elif node.type != "VOLUME_ABSORPTION":
        why = "only Volume Absorption is supported (no scattering, no emission)"
    else:
        try:  # Cycles: absorption (1 - Color) x Density, both clamped at 0
            color = np.maximum(constant(node, "Color"), 0.0)
            kw["absorb"] = np.maximum(1.0 - color, 0.0) * max(float(constant(node, "Density")), 0.0)
        except Unsupported as e:
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
    if tree is None or not uses_nodes(mat):
        return diffuse("material has no shader nodes", np.array(mat.diffuse_color[:3], float))
    try:
        out = output_node(tree, "OUTPUT_MATERIAL")
        if out is None:
            raise Unsupported("node tree has no output node")
        src = follow(out.inputs["Surface"])
        if src is None:
            return _black(mat, warn, "nothing is linked to the Material Output's Surface")
        if src[0].type not in _MIXES:
            return bsdf(src[0], mat, warn, direct=True)
        parts, left = _parts(src[0], mat, warn, 0)
        if not parts and not left:
            return _black(mat, warn, "its shader mix has no closures")
        return _mixed(parts, left, mat, warn)
    except Unsupported as e:
        return diffuse(str(e))


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
        return [(1.0, bsdf(node, mat, warn), node.name)], []
    if node.mute:
        raise Unsupported(f"node '{node.name}' is muted")
    if depth >= MAX_MIX_DEPTH:
        raise Unsupported("node tree is too deep")
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
            fac = min(max(float(constant(node, node.inputs[0].name)), 0.0), 1.0)
        except Unsupported as e:
            raise Unsupported(f"{e}: a Mix Shader's Factor must be a constant") from None
        inputs = [(1.0 - fac, node.inputs[1]), (fac, node.inputs[2])]
    parts, left = [], []
    for w, sock in inputs:
        src = follow(sock)
        if not w > 0.0 or src is None:
            continue
        try:
            p, lf = _parts(src[0], mat, warn, depth + 1)
        except Unsupported as e:
            left.append((w, src[0].name, str(e)))
            continue
        parts += [(w * pw, kw, name) for pw, kw, name in p]
        left += [(w * lw, name, why) for lw, name, why in lf]
    return parts, left


def _shadow_ray_factor(mix) -> bool:
    """Is a Mix Shader's Factor Light Path's Is Shadow Ray?"""
    src = follow(mix.inputs[0])
    return src is not None and not src[0].mute and src[0].type == "LIGHT_PATH" and src[1].name == "Is Shadow Ray"


def _fresnel_index(mix):
    """The index of the Fresnel node (or Layer Weight's Fresnel output) driving a Mix Shader's Factor,
    or None: Cycles' dielectric Fresnel of the incoming direction at the shading normal, for that
    index (Layer Weight: 1 / (1 - Blend)) and its inverse from the back."""
    src = follow(mix.inputs[0])
    if src is None or src[0].mute:
        return None
    node, out = src
    if node.type == "FRESNEL" or (node.type == "LAYER_WEIGHT" and out.name == "Fresnel"):
        if is_linked(node, "Normal"):
            raise Unsupported(f"the Normal of node '{node.name}' driving the Factor of '{mix.name}' is linked")
        if node.type == "FRESNEL":
            return max(float(constant(node, "IOR")), 1.0 + 1e-5)
        return 1.0 / max(1.0 - float(constant(node, "Blend")), 1e-5)
    return None


def _fresnel_mix(mix, ior, mat, warn) -> dict:
    """A Mix Shader weighed by a Fresnel node: Cycles' old glass (Refraction and Glossy) is a Glass
    BSDF whose reflection and refraction keep their own colours, and Blender's old coated floor
    (Diffuse and Glossy) is a diffuse under a smooth coat of that index (layer.py's weight 1 - F(mu)
    towards the eye: its table at Roughness 0 is exactly that)."""
    sides = []
    for sock in mix.inputs[1:3]:
        src = follow(sock)
        sides.append(None if src is None else (bsdf(src[0], mat, warn), src[0].name))
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
    raise Unsupported(f"the Factor of Mix Shader '{mix.name}' is a Fresnel: read for a Refraction BSDF and a "
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
        raise Unsupported(f"no part of its shader mix is supported ({why})")
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


class MaterialTable:
    """The builder's material ids of a scene's bpy materials, each classified once (keyed by its
    original's name_full; None: the default diffuse), and which of them are bumped mirrors and glass
    (bump_specs: builder id -> bump_of's (kind, node name, Distance, Strength, flips) and the
    original bpy Material)."""

    def __init__(self, builder, warn):
        self.builder, self.warn = builder, warn
        self.index = {}  # material name_full -> builder index
        self.bump_specs = {}

    def id_of(self, mat) -> int:
        """The builder's id of bpy Material mat (None: the default diffuse), added on first use."""
        b, mat_index = self.builder, self.index
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
            kw = classify_material(mat, self.warn)
            mat_index[key] = b.material(key, **kw, bump_correction=corr)
            spec = bump_of(mat) if kw["kind"] in (S.DIELECTRIC, S.CONDUCTOR) else None
            if spec is not None:
                orig_mat = mat.original if getattr(mat, "original", None) is not None else mat
                self.bump_specs[mat_index[key]] = spec + (orig_mat,)
        return mat_index[key]
