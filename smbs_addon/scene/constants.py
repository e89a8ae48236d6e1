"""The scene's codes and limits: material kinds, Fresnel models, light types and shapes, Cycles' Ray
Visibility bits, and the largest values a scene may hold. Scene arrays (arrays.py) and their checks
(validate.py) share them.
"""
from __future__ import annotations

import numpy as np

FORMAT_VERSION = 1

# Material classes (Scene.mat_kind)
DIFFUSE, CONDUCTOR, DIELECTRIC, EMITTER = 0, 1, 2, 3
MATERIAL_KINDS = ("diffuse", "conductor", "dielectric", "emitter")
# Fresnel models (Scene.mat_fresnel). Conductors: Glossy BSDF (constant colour, NONE), Cycles'
# F82-Tint metal (SCHLICK: Schlick from F0 = mat_color towards white, less B cos (1 - cos)^6 with
# B = mat_metal[:, :3], zero without; a Principled BSDF's metallic lobe, the Metallic BSDF's F82
# mode) or a physical conductor (CONDUCTOR: the Fresnel equations of complex index n + ik,
# mat_metal's n and k per channel; the Metallic BSDF's Physical Conductor mode; mat_color then
# holds its reflectance at normal incidence). Dielectrics: glass (NONE: the dielectric Fresnel
# term splits reflection and refraction; a Principled glass's Specular Tint c scales its value at
# normal incidence, mat_metal[:, :3] = c - 1, zero without) or Cycles' Refraction BSDF (REFRACTION_ONLY: transmits
# its colour with no Fresnel term and no reflection; total internal reflection absorbs).
FRESNEL_NONE, FRESNEL_SCHLICK, REFRACTION_ONLY, FRESNEL_CONDUCTOR = 0, 1, 2, 3
FRESNEL_MODELS = ("none", "F82-Tint", "refraction only", "physical conductor")  # by index

# Light types (Scene.light_type), as Cycles defines them; WORLD is a world of constant colour
# (a Background node): radiance light_color from every direction, at infinity; MESH is a mesh
# light (an object's triangles of an emitter material, Scene.tri_light): radiance light_color
# from both sides of each triangle, as Cycles' Emission shader shines
POINT, SPOT, AREA, SUN, WORLD, MESH = 0, 1, 2, 3, 4, 5
LIGHT_TYPES = ("POINT", "SPOT", "AREA", "SUN", "WORLD", "MESH")
DISTANT = (SUN, WORLD)  # lights at infinity: a path's light end is a direction
# Area light shapes (Scene.light_shape)
SQUARE, RECTANGLE, DISK, ELLIPSE = 0, 1, 2, 3
AREA_SHAPES = ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE")

PERSP, ORTHO = 0, 1

# Cycles' Ray Visibility (an object's or a light's Object > Visibility > Ray Visibility; the world's
# World > Settings): which rays meet it, as bits of Scene.object_visibility and light_visibility. A
# ray's kind is the event at the vertex it leaves, from the camera: a diffuse receiver's bounce casts
# a diffuse ray, a mirror's reflection or a glass's (inside too) a glossy one, a refraction a
# transmission one
RAY_CAMERA, RAY_DIFFUSE, RAY_GLOSSY, RAY_TRANSMISSION, RAY_SHADOW = 1, 2, 4, 8, 16
RAY_ALL = 31
PATH_RAYS = RAY_DIFFUSE | RAY_GLOSSY | RAY_TRANSMISSION  # a caustic path's rays after the camera's

# fields a scene file may lack (saved before they were exported): their defaults hold
OPTIONAL = ("light_paths", "mat_bump_correction", "mat_layer", "mat_textured", "mat_absorb", "world_map",
            "world_map_rotation", "mat_distribution", "tri_normals_back", "mat_view_bump", "view_normals",
            "view_points", "object_visibility", "light_visibility", "tri_light", "mat_emission", "mat_metal",
            "light_links", "light_blockers", "mat_film")
SENSOR_FITS = ("AUTO", "HORIZONTAL", "VERTICAL")
MAX_FILTER_WIDTH = 10.0  # pixels: Cycles' pixel filter width is from 0.01 to 10
MAX_BOUNCES = 1024  # Blender's Light Paths bounce limits go up to this
MAX_POWER = 1e20  # a light's power (W) or a sun's strength: past it a caustic overflows float32
NO_FILM = (0.0, 1.33)  # a material's mat_film row without a film (Blender's default Thin Film IOR)
MAX_COLOR = 1e6  # a material's colour channel (an albedo, 1 at most in a physical scene)


def flat_axes(m3) -> bool:
    """Does a 3x3 linear part lose a dimension (an axis scaled to zero, or the axes in a plane),
    relative to its own scale?"""
    m = np.asarray(m3, float)
    return not (abs(np.linalg.det(m)) > 1e-12 * max(float(np.abs(m).max()), 1e-300) ** 3)
