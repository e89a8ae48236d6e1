"""The compiled kernels' interface: record layouts and codes that the kernels and their callers
share by name, defined once here.

Packed arrays are read through named column offsets (a chain vertex's F columns, a photon's splat
record, a gather segment, the camera's parameters); tuples of arrays passed whole are named tuples
(records) whose fields the kernels read by name. numba compiles a named tuple's field as it does a
tuple's item: the names cost nothing at run time.

Chain vertices are packed: F (N, k, NF) float64 with the columns below, I (N, k, 3) int64
(prim, obj, mat).
"""
from __future__ import annotations

import numpy as np

# packed vertex columns
P, NG, NS, S, T, DNS, DNT = 0, 3, 6, 9, 12, 15, 18
NF = 21


def chain_kinds(types: str) -> np.ndarray:
    """A chain type's vertices as the kernels take them: 1 for a refraction (T), 0 for a
    reflection (R)."""
    return np.array([1 if c == "T" else 0 for c in types], np.int64)


PRIM, OBJ, MAT = 0, 1, 2  # a vertex's I columns

# a walk's outcome (its lane's status after a seed, a trace or a walk), by code
(OK, MISS, NOT_CASTER, WRONG_MATERIAL, TIR, SIDE, SEED_OBJECT, SINGULAR, MAX_ITER, WRONG_END, OCCLUDED,
 TIR_INNER, SIDE_INNER, STALLED) = range(14)
OUTCOMES = ("converged", "miss", "not_caster", "wrong_material", "tir", "side", "seed_object",
            "singular", "max_iterations", "wrong_end", "occluded", "tir_inner", "side_inner", "stalled")
# SMBS's large-mutation triggers, by code
TRIG_NONE, TRIG_TIR, TRIG_BACKLIT, TRIG_SLOW = 0, 1, 2, 3
TRIGGERS = ("none", "tir", "backlit", "slow")
# the surfaces of objects a ray's kind does not meet (Scene.hidden_kinds) it passes, at most: past them
# it counts as a miss (a maze of hidden glass)
HIDDEN_PASSES = 16
# ray kinds the walk kernels count (embree.ray_state's counters)
RAYS_SEED, RAYS_WALK = 0, 1
# the shapes segments_near tests (a row of NEAR_F numbers per light)
NEAR_ALL, NEAR_NONE, NEAR_SPHERE, NEAR_RECT, NEAR_DISK = 0, 1, 2, 3, 4
NEAR_F = 15


# ------------------------------------------------------------------ the light tracer's photons
# tally entries of photon_lanes: photons with flux, specular paths cut at max_bounces, lanes a
# shading normal stopped (scatter1 said no), paths whose events left Cycles' Light Paths limits
PH_PHOTONS, PH_TRUNCATED, PH_LOST, PH_BEYOND = 0, 1, 2, 3
PH_TALLY = 4
# a splat record: the diffuse vertex (point, geometric and shading normals), the direction the
# photon arrived from (away from the surface), its flux; and (lane, specular bounces, material)
REC_P, REC_NG, REC_NS, REC_W, REC_BETA = 0, 3, 6, 9, 12
REC_F = 15


# ------------------------------------------------------------------ eye paths
# camera.CameraModel.kernel_params: the origin, the axes (row by row: world x, y, z of the camera's
# x, y, z columns), the view plane's corner and pixel size, the height in pixels, 1 if orthographic,
# the near clip distance
CAM_ORIGIN, CAM_AXES, CAM_XMIN, CAM_YMIN, CAM_PIX_W, CAM_PIX_H, CAM_H, CAM_ORTHO, CAM_CLIP = 0, 3, 12, 13, 14, 15, 16, \
    17, 18
# ... the far clip distance, a pixel's area on the view plane, world -> camera (row by row), the
# render region (x0, x1, y0, y1 raster pixels)
CAM_CLIP_END, CAM_PIX_AREA, CAM_INV, CAM_REGION = 19, 20, 21, 30
CAM_F = 34


# a point of Scene.view_points is the receiver's own where it lies on its plane within this share of the
# sub-pixel's footprint, and at most VIEW_NEAR footprints from it
VIEW_PLANE, VIEW_NEAR = 0.05, 4.0


# ------------------------------------------------------------------ the light tracer's gathering
# a segment record of gather_lanes (after a specular vertex on a caster: the caller looks for
# lights on it): origin, direction, distance to the next surface (inf: none), throughput, 1 if the
# vertex it leaves reflected (a glossy ray; 0: a refraction, a transmission ray), the object of that
# vertex (Light Linking's)
SEG_O, SEG_D, SEG_T, SEG_BETA, SEG_REFL, SEG_OBJ = 0, 3, 6, 7, 10, 11
SEG_F = 12
# a vertex record (a diffuse vertex after a specular one on a caster, lit directly by the caller):
# point, geometric and shading normals, the direction back along the path, throughput x albedo, its object
VX_P, VX_NG, VX_NS, VX_W, VX_BETA, VX_OBJ = 0, 3, 6, 9, 12, 15
VX_F = 16


