"""One BSDF node of a material's node tree -> ``SceneBuilder.material`` keywords (its kind, colours,
index, roughness, Fresnel, layering, film), a helper per kind of node: Principled (a metal, a glass or
a layered diffuse, whichever lobe weighs most), Metallic, Glass, Refraction, Glossy, Diffuse, Emission.
What cannot be represented raises ``Unsupported``; what is left out is said through ``warn``."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..scene import arrays as S
from ..shading import thinfilm
from ..shading.coat import principled_layer
from ..shading.microfacet import GGX, MULTI_GGX, SINGULAR_ALPHA2
from ..shading.fresnel import conductor_f0, f82_tint_metal
from .bump_nodes import BUMPABLE, normal_source
from .nodes import Unsupported, constant, constant_or, follow, image_linear, is_linked

DEFAULT_ALBEDO = 0.8


def _colour(node, name):
    """(colour, textured) of a colour input: constant's value, or where a node other than an RGB
    one drives it (an image or procedural texture, a mix of them: something that varies over the
    surface), a stand-in and True: the mean of a Checker Texture's two constant colours or of an
    Image Texture's pixels, else DEFAULT_ALBEDO. Cycles' Diffuse Color pass holds the texture's value where the camera sees
    the surface (BakeResult.per_albedo)."""
    try:
        return constant(node, name), False
    except Unsupported:
        src = follow(node.inputs[name])
        if src is None:
            raise
    tex = src[0]
    if tex.type == "TEX_CHECKER":
        try:
            return 0.5 * (constant(tex, "Color1") + constant(tex, "Color2")), True
        except Unsupported:
            pass
    if tex.type == "TEX_IMAGE" and src[1].name == "Color":
        mean = _image_mean(tex.image)
        if mean is not None:
            return mean, True
    return np.full(3, DEFAULT_ALBEDO), True


MAX_MEAN_PIXELS = 4096 * 4096  # an image's mean is read for its stand-in colour up to this size


def _image_mean(img):
    """The mean linear RGB of an image (image_linear), or None."""
    rgb = image_linear(img, MAX_MEAN_PIXELS)
    if rgb is None:
        return None
    mean = rgb.reshape(-1, 3).mean(axis=0, dtype=np.float64)
    return mean if np.all(np.isfinite(mean)) else None


def _say_textured(mat, stand_in, warn):
    warn(f"material '{mat.name}': its colour is a texture: where the camera sees it, the caustic takes "
         f"the render's Diffuse Color pass (composited); seen through mirrors or glass, and in light it "
         f"passes on, it counts as albedo {float(np.mean(stand_in)):.3g}")


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


def _has_film(node) -> bool:
    """Is a node's Thin Film Thickness linked or above Cycles' cutoff (0.1 nm, THINFILM_THICKNESS_CUTOFF,
    compared in float32 as Cycles does)?"""
    sock = node.inputs.get("Thin Film Thickness")
    return sock is not None and (follow(sock) is not None or np.float32(sock.default_value) > np.float32(thinfilm.CUTOFF))


def _film(node, mat, warn) -> tuple:
    """A node's thin film as Scene.mat_film holds it: (Thin Film Thickness in nm, Thin Film IOR), S.NO_FILM
    where it is Cycles' cutoff thin or less. A thickness or index driven by nodes is not read (warned
    about): no film."""
    sock = node.inputs.get("Thin Film Thickness")
    if not _has_film(node):
        return S.NO_FILM
    if follow(sock) is not None or is_linked(node, "Thin Film IOR"):
        warn(f"material '{mat.name}': the thin film of '{node.name}' is driven by nodes (a textured thickness or "
             f"index): its iridescence is not baked")
        return S.NO_FILM
    return float(sock.default_value), max(float(node.inputs["Thin Film IOR"].default_value), 1e-5)


def _anisotropy(node, name, roughness) -> list:
    """['anisotropy'] where a rough node's anisotropy input is linked or not 0 (a perfect mirror has
    none to show)."""
    sock = node.inputs.get(name)
    if sock is None or not (follow(sock) is not None or float(sock.default_value) != 0.0):
        return []
    rough = node.inputs.get("Roughness")
    return ["anisotropy"] if (rough is not None and follow(rough) is not None) or float(roughness) > 0 else []


def _metallic(node, mat, warn) -> dict:
    """The Metallic BSDF (Blender 4.3 on): Cycles' F82-Tint metal (Base Color, Edge Tint) or a physical
    conductor (IOR n and Extinction k per channel), the roughness and distribution of a Glossy BSDF."""
    r = constant(node, "Roughness")
    film = _film(node, mat, warn)
    ignored = _anisotropy(node, "Anisotropy", r)
    if ignored:
        warn(f"material '{mat.name}': the {' and '.join(ignored)} of Metallic BSDF '{node.name}' ignored")
    if getattr(node, "fresnel_type", "F82") == "PHYSICAL_CONDUCTOR":
        n = np.maximum(constant(node, "IOR"), 0.0)
        k = np.maximum(constant(node, "Extinction"), 0.0)
        if not np.any(np.concatenate([n, k]) > 0):
            raise Unsupported(f"Metallic BSDF '{node.name}' has IOR and Extinction 0 (no conductor)")
        return dict(kind=S.CONDUCTOR, color=conductor_f0(n, k), roughness=r, fresnel=S.FRESNEL_CONDUCTOR,
                    reflect_color=np.ones(3), ior=1.0, metal=np.concatenate([n, k]),
                    distribution=_distribution(node, mat, warn, r), film=film)
    f0 = np.clip(constant(node, "Base Color"), 0.0, 1.0)
    tint = np.clip(constant(node, "Edge Tint"), 0.0, 1.0)
    return dict(kind=S.CONDUCTOR, color=f0, roughness=r, fresnel=S.FRESNEL_SCHLICK, reflect_color=np.ones(3),
                ior=1.0, metal=f82_tint_metal(f0, tint), distribution=_distribution(node, mat, warn, r), film=film)


@dataclass
class _Principled:
    """What the export reads of a Principled BSDF (_principled_inputs)."""
    base: np.ndarray  # Base Color (a stand-in where textured: _colour)
    textured: bool
    metallic: float
    rough: float
    trans: float  # Transmission Weight
    ior: float
    emission: np.ndarray  # Emission Color x Strength (0 where not ours)
    coat_w: float  # the clear coat's weight over a diffuse receiver (0 where not ours)
    film: tuple  # Scene.mat_film's (thickness, index), S.NO_FILM where none
    edge_tint: np.ndarray  # a metal's Specular Tint (white where textured)


def _active(node, sock_name, nonzero=lambda v: float(v) > 0) -> bool:
    """Is a node's input linked, or its value one that does something (nonzero)?"""
    sock = node.inputs.get(sock_name)
    return sock is not None and (follow(sock) is not None or nonzero(sock.default_value))


def _principled_emission(node, ignored) -> np.ndarray:
    """A Principled BSDF's emission: a mesh light of radiance Emission Color x Strength (builder);
    none where it is textured or under a coat or sheen (appended to `ignored`)."""
    emission = np.zeros(3)
    if _active(node, "Emission Strength") and _active(node, "Emission Color", lambda c: max(c[:3]) > 0):
        # Cycles puts the emission under the coat and the sheen, which take an angle-dependent share of it
        textured_glow = is_linked(node, "Emission Color") or is_linked(node, "Emission Strength")
        if textured_glow or _active(node, "Coat Weight") or _active(node, "Sheen Weight"):
            ignored.append("emission (textured)" if textured_glow else "emission (under a coat or sheen)")
        else:
            emission = constant(node, "Emission Color")[:3] * float(constant(node, "Emission Strength"))
    return emission


def _principled_coat(node, receiver, ignored) -> float:
    """A Principled BSDF's clear coat weight over a diffuse receiver: it takes its share towards the
    eye (layer.py); its tint's absorption, its own normal, and a coat over metal or glass are not ours
    (0, appended to `ignored`)."""
    if not _active(node, "Coat Weight"):
        return 0.0
    tint_c = constant_or(node, "Coat Tint", np.ones(3))
    if receiver and np.allclose(tint_c, 1.0) and not is_linked(node, "Coat Normal"):
        return float(min(constant(node, "Coat Weight"), 1.0))
    ignored.append("coat")
    return 0.0


def _principled_inputs(node, mat, warn, direct) -> _Principled:
    """A Principled BSDF's inputs, what of them is ignored said in one warning (raises Unsupported
    for a textured metal or glass)."""
    base, textured = _colour(node, "Base Color")
    metallic = constant(node, "Metallic")
    rough = constant(node, "Roughness")
    trans = constant(node, "Transmission Weight")
    ior = constant(node, "IOR")
    ignored = []
    emission = _principled_emission(node, ignored)
    receiver = metallic < 0.5 and trans < 0.5
    coat_w = _principled_coat(node, receiver, ignored)
    for sock_name, label in (("Sheen Weight", "sheen"), ("Subsurface Weight", "subsurface")):
        if _active(node, sock_name):
            ignored.append(label)
    # a thin film: over a metal's or a glass's Fresnel (and the metal's coat), baked; over a diffuse's
    # coat, Cycles' share of the diffuse under it (the coat's reflectance with the film) is not ours
    film = _film(node, mat, warn)
    if film[0] > 0 and not (metallic >= 0.5 or trans >= 0.5):
        ignored.append("thin film (over a diffuse)")
    ignored += _anisotropy(node, "Anisotropic", rough)
    # a metal's Specular Tint is its edge's tint (F82-Tint); a textured one is left white
    try:
        edge_tint = np.minimum(constant_or(node, "Specular Tint", np.ones(3)), 1.0)
    except Unsupported:
        edge_tint = np.ones(3)
        if metallic >= 0.5:
            ignored.append("specular tint (textured)")
    a = node.inputs.get("Alpha")
    if a is not None and (follow(a) is not None or float(a.default_value) < 1.0):
        ignored.append("alpha")
    # a receiver's bump: read from the view where the camera sees it (cycles_passes.view_maps); a
    # mirror's or glass's: baked (bump.py)
    if is_linked(node, "Normal") and not (direct and (receiver or normal_source(node) is not None)):
        ignored.append("normal map")
    if ignored:
        warn(f"material '{mat.name}': Principled BSDF {', '.join(ignored)} ignored")
    if textured and (metallic >= 0.5 or trans >= 0.5):
        raise Unsupported("a textured Base Color is supported on diffuse surfaces only")
    if textured:
        _say_textured(mat, base, warn)
    return _Principled(base, textured, metallic, rough, trans, ior, emission, coat_w, film, edge_tint)


def _principled(node, mat, warn, direct) -> dict:
    """A Principled BSDF. Cycles weighs the metal lobe by Metallic and the glass by (1 - Metallic) x
    Transmission; a material is the lobe that weighs most, the rest of it is left out (and said so)."""
    p = _principled_inputs(node, mat, warn, direct)
    if p.metallic >= 0.5:
        return _principled_metal(node, mat, warn, p)
    if p.trans >= 0.5:
        return _principled_glass(node, mat, warn, p)
    return _principled_diffuse(node, p, direct)


def _principled_metal(node, mat, warn, p) -> dict:
    """A Principled metal: the rest is a dielectric coat (a mirror at Roughness 0: it casts) over a
    diffuse."""
    level = constant_or(node, "Specular IOR Level", 0.5)
    eta, _ = principled_layer(p.ior, level, np.ones(3))
    if p.metallic < 1.0:
        warn(f"material '{mat.name}': Principled BSDF Metallic {p.metallic:g}: the diffuse under "
             f"its coat ({1 - p.metallic:.0%} of it) receives no caustics")
    # Cycles' metal lobe: F82-Tint from F0 = the Base Color, its Specular Tint the edge's tint
    f0 = np.clip(p.base, 0.0, 1.0)
    return dict(kind=S.CONDUCTOR, color=f0, roughness=p.rough, fresnel=S.FRESNEL_SCHLICK,
                reflect_color=np.full(3, float(p.metallic)), ior=eta if eta > 1.0 else 1.0,
                distribution=_distribution(node, mat, warn, p.rough), emission=p.emission,
                metal=f82_tint_metal(f0, p.edge_tint), film=p.film)


def _principled_glass(node, mat, warn, p) -> dict:
    """A Principled glass. Cycles' tints transmission by sqrt(base colour) at every refraction and
    leaves reflection white; its Specular Tint scales the Fresnel term's value at normal incidence
    (Scene.mat_metal[:3] = tint - 1; optics._tinted_glass)."""
    w_glass = float((1.0 - p.metallic) * p.trans)
    if w_glass < 1.0:
        warn(f"material '{mat.name}': Principled BSDF glass of weight {w_glass:.2f} ((1 - Metallic) x "
             f"Transmission); the rest neither casts nor receives caustics")
    try:
        spec_tint = np.maximum(constant_or(node, "Specular Tint", np.ones(3)), 0.0)
    except Unsupported:
        spec_tint = np.ones(3)
        warn(f"material '{mat.name}': Principled BSDF Specular Tint driven by nodes (textured) on glass "
             f"ignored")
    return dict(kind=S.DIELECTRIC, color=np.sqrt(np.clip(p.base, 0.0, 1.0)) * w_glass,
                reflect_color=np.full(3, w_glass), ior=p.ior, roughness=p.rough,
                distribution=_distribution(node, mat, warn, p.rough), emission=p.emission, film=p.film,
                metal=np.concatenate([spec_tint - 1.0, np.zeros(3)]))


def _principled_diffuse(node, p, direct) -> dict:
    """The diffuse under Cycles' layers: what metallic and transmission leave, beneath a dielectric
    glossy layer that takes its share towards the eye (layer.py)."""
    level = constant_or(node, "Specular IOR Level", 0.5)
    tint = constant_or(node, "Specular Tint", np.ones(3))
    eta, tint_max = principled_layer(p.ior, level, tint)
    # Cycles' Oren-Nayar from a Diffuse Roughness of 1e-5 (CLOSURE_WEIGHT_CUTOFF)
    sigma = constant_or(node, "Diffuse Roughness", 0.0)
    sigma = float(min(sigma, 1.0)) if sigma >= 1e-5 else 0.0
    coat_ior = float(constant_or(node, "Coat IOR", 1.5))
    coat_rough = float(constant_or(node, "Coat Roughness", 0.03))
    return dict(kind=S.DIFFUSE, color=p.base * (1.0 - p.metallic) * (1.0 - p.trans), roughness=p.rough,
                layer=(eta, float(p.rough), tint_max, (1.0 - p.metallic) * (1.0 - p.trans), sigma,
                       p.coat_w, coat_ior, coat_rough), textured=p.textured,
                view_bump=direct and is_linked(node, "Normal"), emission=p.emission)


def _glass(node, mat, warn) -> dict:
    """A Glass BSDF: Color tints reflection and refraction alike."""
    c = constant(node, "Color")
    r = constant(node, "Roughness")
    return dict(kind=S.DIELECTRIC, color=c, reflect_color=c.copy(), ior=constant(node, "IOR"), roughness=r,
                distribution=_distribution(node, mat, warn, r), film=_film(node, mat, warn))


def _refraction(node, mat, warn) -> dict:
    """A Refraction BSDF (Cycles: transmits Color, no Fresnel term, no reflection)."""
    r = constant(node, "Roughness")
    return dict(kind=S.DIELECTRIC, color=constant(node, "Color"), reflect_color=np.zeros(3),
                ior=constant(node, "IOR"), roughness=r, fresnel=S.REFRACTION_ONLY,
                distribution=_distribution(node, mat, warn, r))


def _glossy(node, mat, warn) -> dict:
    """A Glossy (or old Anisotropic) BSDF: a mirror of colour Color, no Fresnel term."""
    if _has_film(node):
        warn(f"material '{mat.name}': the thin film of '{node.name}' ignored")
    if node.inputs.get("Anisotropy") is not None and (
            is_linked(node, "Anisotropy") or float(node.inputs["Anisotropy"].default_value) != 0):
        warn(f"material '{mat.name}': Glossy BSDF anisotropy ignored")
    r = constant(node, "Roughness")
    return dict(kind=S.CONDUCTOR, color=constant(node, "Color"), roughness=r, fresnel=S.FRESNEL_NONE,
                distribution=_distribution(node, mat, warn, r))


def _diffuse(node, mat, warn, direct) -> dict:
    """A Diffuse BSDF (Cycles' Oren-Nayar from a Roughness of 1e-5)."""
    sigma = float(constant(node, "Roughness"))
    color, textured = _colour(node, "Color")
    if textured:
        _say_textured(mat, color, warn)
    if is_linked(node, "Normal") and not direct:
        warn(f"material '{mat.name}': the Normal of '{node.name}' is driven by a node (a bump or normal map) "
             f"inside a shader mix: the caustic on it is shaded with the unbumped normal, where Cycles' follows "
             f"the bumps")
    return dict(kind=S.DIFFUSE, color=color, roughness=sigma, textured=textured,
                layer=(0.0, 0.0, 0.0, 1.0, min(sigma, 1.0) if sigma >= 1e-5 else 0.0, 0.0, 0.0, 0.0),
                view_bump=direct and is_linked(node, "Normal"))


def _emission(node) -> dict:
    """An Emission node: a mesh light of radiance Color x Strength."""
    return dict(kind=S.EMITTER, color=constant(node, "Color"),
                strength=constant(node, "Strength"))


def bsdf(node, mat, warn, direct=False) -> dict:
    """Material keywords for one BSDF node (raises Unsupported for a node we cannot represent);
    direct: the node is the material's surface (no mix), where a Bump node on its Normal is ours."""
    if node.mute:
        raise Unsupported(f"node '{node.name}' is muted")
    t = node.type
    if t == "BSDF_PRINCIPLED":
        return _principled(node, mat, warn, direct)
    if t in BUMPABLE and is_linked(node, "Normal") and not (direct and normal_source(node) is not None):
        warn(f"material '{mat.name}': the Normal of '{node.name}' is driven by nodes the export cannot bake "
             f"(a Bump node below another node, a node group, a mesh attribute, a bump inside a shader mix): its "
             f"caustic is baked from the unbumped surface, where Cycles' follows the bumps")
    if t == "BSDF_METALLIC":
        return _metallic(node, mat, warn)
    if t == "BSDF_GLASS":
        return _glass(node, mat, warn)
    if t == "BSDF_REFRACTION":
        return _refraction(node, mat, warn)
    if t in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
        return _glossy(node, mat, warn)
    if t == "BSDF_DIFFUSE":
        return _diffuse(node, mat, warn, direct)
    if t == "EMISSION":
        return _emission(node)
    raise Unsupported(f"node '{node.name}' is not supported")
