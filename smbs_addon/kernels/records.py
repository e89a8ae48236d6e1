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

from collections import namedtuple

import numpy as np

# packed vertex columns
P, NG, NS, S, T, DNS, DNT = 0, 3, 6, 9, 12, 15, 18
NF = 21


# a chain vertex's kind (chain_kinds)
REFLECT, REFRACT = 0, 1


def chain_kinds(types: str) -> np.ndarray:
    """A chain type's vertices as the kernels take them: REFRACT for a T, REFLECT for an R."""
    return np.array([REFRACT if c == "T" else REFLECT for c in types], np.int64)


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
# the self-intersection offset per unit of coordinate, scene.offset_eps's: 67 float32 ulps (2^-24 each)
# for embree's float32 vertices and arithmetic against the float64 hit points (chain.offset1)
EPS_REL = 4e-6
# the most of the smallest planned caster's size that offset may take (Tracer.set_extent): a
# hundredth of a millimetre on a 10 cm caster
EPS_OF_CASTER = 1e-4
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
# a connect record (a later diffuse vertex on a planned receiver whose caustic the walks estimate, the
# events before it and its own bounce fitting): point, geometric and shading normals, the direction
# back along the path, the throughput (before its albedo), its material, its events so far (diffuse,
# glossy, transmission)
CX_P, CX_NG, CX_NS, CX_W, CX_BETA, CX_MAT, CX_CNT = 0, 3, 6, 9, 12, 15, 16
CX_F = 19




# ------------------------------------------------------------------ records: tuples passed whole, by name
# The scene as the kernels trace paths through it (tracer.Tracer.kernel_geometry): the triangles'
# vertices (T,3,3), unit geometric normals (T,3), corner normals (T,3,3) or (T,6,3) (chain._corners);
# per triangle its material and object; per material its kind (scene.DIFFUSE...) and IOR; per object
# whether it is a planned caster and the kinds of ray it does not meet (Scene.hidden_kinds; empty: none)
Geometry = namedtuple("Geometry", "tv tng tns tri_material mat_kind tri_object casters mat_ior hid")

# Chain rows a ray traces (chain.trace_lane): vertices F (N,k,NF), I (N,k,3), the walk outcome
# per row, the unit direction leaving the last vertex (N,3)
ChainRows = namedtuple("ChainRows", "F I status out_dir")

# Float64 hit records of a batch of rays (chain.intersect_rays): primitive (-1: a miss), distance,
# point, geometric normal, shading normal, barycentrics (b1, b2)
HitRows = namedtuple("HitRows", "prim t p ng ns b")

# A lane's light end (shading.light_samples.LightEnd's arrays): a point (or, directional, a unit
# direction towards the light) and its tangents, (N,3) each
LightRows = namedtuple("LightRows", "y ys yt directional")

# The walk's settings (walks.walk.kernel_config; WalkConfig's, in the kernels' types): the constraint
# form (True: half-vector), the chain's vertex kinds (chain_kinds), SMBS and its triggers (TIR,
# back-lit at vertex backlit_at (-1: none), slow: tau, slow_run), tir_rejected, min_beta, the
# convergence threshold, the longest step, the ray offset eps, GetRatio's halvings, the iterations,
# the first step's beta and the stall rule (window, factor, from)
WalkSettings = namedtuple("WalkSettings", "hv kinds smbs tir backlit slow tir_rejected backlit_at tau slow_run "
                                          "min_beta threshold max_step eps max_halvings max_iterations beta0 "
                                          "stall_window stall_factor stall_from")

# The walk's inputs per lane (walks.walk.newton_walk): x0 and its geometric normal, the light end,
# the etas of the chain's vertices (written by the walk), whether the lane may mutate large, and the
# objects' bounding boxes (SMBS's GetRatio)
WalkLanes = namedtuple("WalkLanes", "x0 ng0 light etas large_ok obj_lo obj_hi")

# The walk's state per lane: the chain (F, I, out_dir), the mismatch and its side, whether the chain
# is valid, beta, SMBS's bisection scale, its pending trigger and slow steps in a row, the walk
# outcome (OK... STALLED), whether it converged, the proposals it made
WalkState = namedtuple("WalkState", "F I out_dir err front valid beta lscale pending slow_n outcome converged "
                                    "mutations")

# The Newton step's work arrays for a chain of k vertices (newton.lane_scratch): the constraints
# C (k,2), the blocks A, B, D, the right-hand sides and the solve's Li, Y, X (k,2,2)
NewtonScratch = namedtuple("NewtonScratch", "C A B D rhs Li Y X")

# One thread's walk work arrays (walk.walk_scratch): the Newton step's, the proposal's chain (one
# row of ChainRows) and the last stall_window mismatches of a walk
WalkScratch = namedtuple("WalkScratch", "newton proposal hist")

# The seed rays of walk_lanes' lanes: unit directions (N,3) and the object each must meet first
# (-1: any)
SeedRays = namedtuple("SeedRays", "d want")

# The unbiased estimator's Bernoulli trials (trials.bernoulli_lanes): the samples (x0, ng0, the
# light point or direction, the first segment's direction d1, the first vertex's object obj1;
# (S, ...) each)
TrialSamples = namedtuple("TrialSamples", "x0 ng0 y d1 obj1")
# ... the seeds' uniform points on the casters: the triangles' area cdf, vertices and objects
CasterSeeds = namedtuple("CasterSeeds", "cdf tv obj")
# ... the cdf's total, the random key, the first sample's index in the batch, the trials at most,
# SMBS's defensive share, the uniqueness threshold
TrialSettings = namedtuple("TrialSettings", "total key p0 max_trials defensive uniqueness")
# ... all of it, with what the trials write: the first successful trial per sample, and the
# walks and Newton steps made (tally (2,))
TrialJob = namedtuple("TrialJob", "samples seeds settings first tally")

# ------------------------------------------------------------------ records of the light paths' kernels
# The light tracer's photons of one light (photons.photon_lanes): origins, unit directions and flux
# (N,3); a soft-falloff light's centre (3,) and radius (0: none); the kinds of ray that see the light
# (scene.RAY_* bits); the objects it lights ((O,) bool, Light Linking; empty: any) and those that do
# not shadow it ((O,) bool, Shadow Linking; empty: none)
PhotonBatch = namedtuple("PhotonBatch", "o d w soft_center soft_radius visibility lit unshadowing")
# ... their paths' rules: indirect photons or caustic ones, the Light Paths limits
# (bounces.Limits.array()), the specular bounces at most (caustic), the events at most (indirect),
# physical units (optics.scatter1's scale)
PhotonRules = namedtuple("PhotonRules", "indirect lim max_bounces max_iter physical")
# ... what they write: splat records (REC_* columns) and (lane, specular bounces, material), the
# hand-off's specular vertices (HIST_* columns) and their triangles, the tally (PH_*)
PhotonOut = namedtuple("PhotonOut", "rec rec_i hist h_prim tally")

# The gather's receivers (gather.gather_lanes): x0, its normals, the direction back to the eye, the
# eye path's throughput (N,3); its material, the camera's events before it (N,3)
# ... and the two uniforms of x0's own bounce direction (N,2), stratified (core.qmc.BOUNCE), or (0,2): keyed
GatherReceivers = namedtuple("GatherReceivers", "p ng ns w_eye beta mat prior u0")
# ... its rules: the Light Paths limits, the specular vertices at most, physical units, whether x0's
# own segments count, which records to write (segments, vertices, connect records), the objects
# whose diffuse vertices the walks connect at (O,) bool, the objects where a path ends (the plan's
# left-out casters, (O,) bool)
GatherRules = namedtuple("GatherRules", "lim max_specular physical count_first want_seg want_vx want_cx receivers ends")
# ... what it writes: segment records (SEG_* columns) and their lanes, vertex records (VX_*) and theirs,
# connect records (CX_*) and theirs
GatherOut = namedtuple("GatherOut", "seg seg_i vx vx_i cx cx_i")

# The hand-off's receivers (handoff.handoff_lanes): x0, its normals (ns: bumped; sn: its smooth
# normal), the direction back to the eye, the throughput, the albedo (N,3); the material (N,)
HandoffReceivers = namedtuple("HandoffReceivers", "p ng ns sn w_eye beta albedo mat")
# ... the triangles its first bounce aims at (indirect.bent_gather; empty: a cosine bounce), their
# cumulative areas and the cdf's guide table (handoff.guide_table)
BentTargets = namedtuple("BentTargets", "cand cdf guide")
# ... what it writes: per lane its segments (K, SEG_BETA + 3: SEG_O, SEG_D, SEG_T, SEG_BETA), their
# number, its specular vertices (HIST_* columns) and their triangles
HandoffOut = namedtuple("HandoffOut", "seg seg_n hist h_prim")

# The eye pass's paths (eye.eye_lanes): the specular bounces at most, the specular vertices a
# receiver needs before it, physical units (optics.scatter1's scale_eta). The defaults: eye.eye_receivers'
EyePaths = namedtuple("EyePaths", "max_bounces min_specular scale_eta", defaults=(32, 0, False))
# ... what it writes: receiver records (REC_* columns), (lane, specular vertices, material), the
# camera's diffuse, glossy and transmission bounces before each
EyeOut = namedtuple("EyeOut", "rec rec_i prior")
# A bumped receiver's normals as the camera sees them (trace.eye.view_tables): flags per material,
# view_normals, view_points, the raster-to-view map t (4,)
ViewTables = namedtuple("ViewTables", "flags normals points t")
# What the shadow rays towards the camera pass (eye.camera_splats): the triangles' geometric
# normals, their objects, the kinds of ray each object does not meet (Scene.hidden_kinds)
CameraHiding = namedtuple("CameraHiding", "tng tri_object hid")
# The camera splats' outputs: raster positions, values (N,3), the albedo (N,3; empty: none)
Splats = namedtuple("Splats", "rx ry val alb")


# a specular vertex the photons and the hand-off record (hist): point, barycentrics (b1, b2), 1 for a
# reflection, 1 on a planned caster, 1 where Cycles' Bump Map Correction bent the normal (the
# hand-off's alone: HIST_F columns; the photons' HIST_BENT)
HIST_P, HIST_B, HIST_REFL, HIST_CASTER, HIST_BENT = 0, 3, 5, 6, 7
HIST_F = 8
