"""The manifold walk: propagation through specular chains and the Newton walk.

Notation: x0 the diffuse receiver point, x1..xk the specular vertices of a
chain of type ``types`` (one letter per vertex: R reflect, T refract), and the
light end y (a point, or a direction for the sun).

Each Newton iteration (Zeltner et al. 2020, sec. 4; Jhang & Chang 2022, alg. 2):
  1. evaluate the constraints and their block-tridiagonal Jacobian;
  2. small mutation: solve for the step of x1 (the other vertices follow by
     propagation), or, for SMBS, a large mutation when a trigger holds;
  3. propagate the ray x0 -> proposal through every reflection/refraction;
  4. accept if the propagation succeeded and (small mutations only) the
     mismatch at the light shrank: beta = min(1, 2 beta); else beta /= 2.
Propagation makes every interior constraint hold exactly, so the walk converges
when the last vertex's outgoing direction points at the light end.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .constraints import ANGLE_DIFF, HALF_VECTOR, LightEnd
from .geometry import vertex_view
from . import kernels, lanes
from .kernels import MAT, NF, propagate_step, spawn_aim, walk_iterate
from .large_mutation import MAX_HALVINGS

# walk outcome codes
(OK, MISS, NOT_CASTER, WRONG_MATERIAL, TIR, SIDE, SEED_OBJECT, SINGULAR, MAX_ITER, WRONG_END, OCCLUDED,
 TIR_INNER, SIDE_INNER) = range(13)
OUTCOMES = ("converged", "miss", "not_caster", "wrong_material", "tir", "side", "seed_object",
            "singular", "max_iterations", "wrong_end", "occluded", "tir_inner", "side_inner")
# large-mutation triggers
NONE, TRIG_TIR, TRIG_BACKLIT, TRIG_SLOW = 0, 1, 2, 3
TRIGGERS = ("none", "tir", "backlit", "slow")


@dataclass
class WalkConfig:
    form: str = ANGLE_DIFF  # constraint form: "ad" (SMS, SMBS) or "hv" (MNEE)
    max_iterations: int = 20
    threshold: float = 1e-6  # on |w_o' - w_o| at the last vertex (radians, scale-free)
    max_step: float = 0.25  # largest tangent step of x1, as a fraction of the scene size
    smbs: bool = False
    tir: bool = True  # SMBS trigger 1: total internal reflection during propagation
    backlit: bool = True  # SMBS trigger 2: light on the wrong side of a vertex for its interaction
    backlit_vertex: str = "single"  # where trigger 2 looks: "single" (default): chains of one vertex
    # only, where the light's side of that vertex decides; "first": x1 of any chain (the paper's
    # x2); "last": the vertex the light meets, against the vertex before it. On chains of two or
    # more the test also fires on valid paths: "first" cut the T R T success of light off a
    # pane's back face from SMS's 0.49 to 0.055, "last" a bevelled cube's from 0.045 to
    # 0.032-0.036, and neither raised any chain's success above SMS's
    # (bench/results/backlit_vertex.md)
    slow: bool = True  # SMBS trigger 3: small steps shrank the mismatch by less than tau
    tau: float = 0.85
    slow_run: int = 2  # trigger 3 fires after this many slow small steps in a row. After one (the
    # first reading) it derailed walks Newton would have finished: conformance lens, T T success
    # 0.061 against SMS's 0.165 (2: 0.133, 3: 0.153); on the hammered mirror, where it is what
    # doubles SMS's success, 1: 0.558, 2: 0.507, 3: 0.463 (SMS 0.233). bench/results/cube_tir.md
    tir_rejected: bool = False  # trigger 1 also when a rejected small step ran into TIR. SMS
    # recovers from that by halving its step; a large mutation there cost the lens 11% of its
    # successes. Trigger 1 stays on for a TIR seed and a chain a large mutation left in TIR
    defensive: float = 0.1  # SMBS: share of trials that walk as plain SMS, so every SMS-reachable
    # solution keeps a non-zero probability and the Bernoulli estimate stays unbiased
    min_beta: float = 2.0**-6  # a walk whose step had to shrink below this is stuck: it fails


@dataclass
class Chain:
    """k vertices over N lanes, packed (geometry.vertex_view: F (N,k,21) float64, I (N,k,3)
    int64), plus each lane's status."""

    F: np.ndarray
    I: np.ndarray
    status: np.ndarray
    out_dir: np.ndarray  # (N,3) direction leaving the last vertex

    @property
    def verts(self) -> list:
        return [vertex_view(self.F, self.I, j) for j in range(self.F.shape[1])]

    def take(self, idx) -> "Chain":
        return Chain(self.F[idx], self.I[idx], self.status[idx], self.out_dir[idx])


MIN_PART = 512  # lanes per thread below which splitting a kernel call does not pay
WALK_BLOCK = 8192  # lanes per block of newton_walk (and samples per block of the Bernoulli trials)


def _joined(parts):
    """The parts' result arrays joined in lane order."""
    if len(parts) == 1:
        return parts[0]
    return tuple(np.concatenate(x) for x in zip(*parts))


def propagate(ctx, x0, ng0, d, types: str, target=None) -> Chain:
    """Trace x0 -> d and follow the chain's reflections/refractions (shading normals).

    Every vertex must be a specular caster; a T vertex must be glass. The
    geometric normal must agree with the interaction (reflection stays on its
    side, refraction crosses), else the chain is rejected (SIDE). With a target, the
    ray is aimed from the offset origin itself, so the hit lands on the proposed point."""
    if target is None:
        o, dirs = ctx.tracer.spawn(x0, ng0, d), d
    else:
        o, dirs = spawn_aim(x0, ng0, d, target, ctx.tracer.eps)
    return trace_chain(ctx, x0, o, dirs, types)


def trace_chain(ctx, x0, o, dirs, types: str, seeding=None) -> Chain:
    """propagate from x0 with the first ray's offset origins o and directions dirs given: one
    intersect call and one kernels.propagate_step call per vertex. seeding (N,) bool: the rows
    whose rays count as seed rays (the lane pool casts seeds and walks together)."""
    scene, tracer = ctx.scene, ctx.tracer
    n = len(x0)
    k = len(types)
    F = np.zeros((n, k, NF))
    I = np.zeros((n, k, 3), np.int64)
    status = np.full(n, OK, np.int64)
    out = np.zeros((n, 3))
    act = np.arange(n)
    prev = x0
    for j, kind in enumerate(types):
        if act.size == 0:
            break
        prim, t = tracer.cast(o, dirs)
        n_seed = 0
        if seeding is not None:
            n_seed = int(np.count_nonzero(seeding[act]))
            ctx.count("rays_seed", n_seed)
        ctx.count("rays_walk", len(o) - n_seed)
        # from the true previous vertex, not the offset ray origin: the chain stays exact. At the
        # last vertex the kernel keeps the vertex of a chain whose exit is TIR (SMBS can mutate
        # from it) and of one whose exit dips below the geometric surface (a shading normal
        # leaning away, as on a normal-mapped mirror): every walk goes on from it, as SMS does
        # from any seed on the caster, and converges only once the exit is valid
        def part(a, b, act=act, o=o, dirs=dirs, prev=prev, prim=prim, t=t, j=j, kind=kind):
            return propagate_step(
                kind == "T", j == k - 1, j, act[a:b], o[a:b], dirs[a:b], prev[a:b], j > 0, prim[a:b], t[a:b],
                tracer.v, tracer.ng, tracer.ns_corner, tracer.eps, scene.tri_material, scene.mat_kind,
                scene.tri_object, ctx.casters, scene.mat_ior, F, I, status, out)

        act, o, dirs, prev = _joined(lanes.run(part, act.size, tracer.threads, MIN_PART))
    return Chain(F, I, status, out)


def end_mismatch(chain: Chain, light: LightEnd):
    """|w_o' - w_o| at the last vertex: the propagated direction against the
    direction to the light end; and whether it points to the light's side."""
    return kernels.end_mismatch(np.arange(len(chain.F)), chain.F, chain.out_dir, light.y, light.directional)


def backlit(cfg: WalkConfig, types: str, x0, chain: Chain, light: LightEnd) -> np.ndarray:
    """SMBS trigger 2 per lane, as the walk tests it (cfg.backlit_vertex): at chain vertex j,
    for a reflection the vertex before it (x0 for j = 0) and the light lie on different sides
    of its surface; for a refraction, on the same side."""
    return kernels.backlit_lanes(kernels.chain_kinds(types), _backlit_at(cfg.backlit_vertex, len(types)),
                                 np.asarray(x0, np.float64), chain.F, np.asarray(light.y, np.float64),
                                 light.directional)


@dataclass
class WalkResult:
    chain: Chain
    converged: np.ndarray
    outcome: np.ndarray
    mutations: np.ndarray  # proposals made per lane (small + large)
    large: dict = field(default_factory=dict)  # trigger name -> count


def _backlit_at(where: str, k: int) -> int:
    """The chain vertex trigger 2 tests for WalkConfig.backlit_vertex; -1: none."""
    if where not in ("single", "first", "last"):
        raise ValueError(f"backlit_vertex must be 'single', 'first' or 'last', not {where!r}")
    return {"first": 0, "last": k - 1}.get(where, 0 if k == 1 else -1)


def kernel_config(ctx, cfg: WalkConfig, types: str) -> tuple:
    """The walk's settings as kernels.walk_iterate takes them."""
    return (cfg.form == HALF_VECTOR, kernels.chain_kinds(types), cfg.smbs, cfg.tir, cfg.backlit, cfg.slow,
            cfg.tir_rejected, _backlit_at(cfg.backlit_vertex, len(types)), cfg.tau, cfg.slow_run, cfg.min_beta,
            cfg.threshold, cfg.max_step * ctx.scale, ctx.tracer.eps, MAX_HALVINGS)


def newton_walk(ctx, cfg: WalkConfig, types: str, x0, ng0, light: LightEnd, chain: Chain,
                large_ok: np.ndarray | None = None) -> WalkResult:
    """Walk every lane's chain to the light end. Lanes whose seed failed keep
    their seed outcome. large_ok (N,) bool: lanes allowed SMBS's large mutations
    (the rest walk as plain SMS).

    The lanes are cut into blocks of WALK_BLOCK (lanes.blocks), each walked in its own loop
    with kernel and intersect calls on the thread that took it, so one block's Python work
    overlaps another's kernels and rays (splitting each call instead left a core idle whenever
    Python ran). Lanes walk independently of each other: the result does not depend on the
    cut."""
    n = len(x0)
    if n <= WALK_BLOCK:
        return _walk_lanes(ctx, cfg, types, x0, ng0, light, chain, large_ok)

    def part(a, b):
        return _walk_lanes(ctx, cfg, types, x0[a:b], ng0[a:b], light.take(slice(a, b)), chain.take(slice(a, b)),
                           None if large_ok is None else large_ok[a:b])

    parts = lanes.blocks(part, n, WALK_BLOCK, ctx.tracer.threads)
    cols = zip(*[(p.chain.F, p.chain.I, p.chain.status, p.chain.out_dir) for p in parts])
    return WalkResult(chain=Chain(*(np.concatenate(c) for c in cols)),
                      converged=np.concatenate([p.converged for p in parts]),
                      outcome=np.concatenate([p.outcome for p in parts]),
                      mutations=np.concatenate([p.mutations for p in parts]),
                      large={t: sum(p.large[t] for p in parts) for t in parts[0].large})


def _walk_lanes(ctx, cfg: WalkConfig, types: str, x0, ng0, light: LightEnd, chain: Chain,
                large_ok: np.ndarray | None) -> WalkResult:
    """newton_walk on one block of lanes."""
    n = len(x0)
    k = len(types)
    chain = Chain(chain.F.copy(), chain.I.copy(), chain.status.copy(), chain.out_dir.copy())
    outcome = chain.status.copy()
    converged = np.zeros(n, bool)
    mutations = np.zeros(n, np.int64)
    beta = np.ones(n)
    err, front = end_mismatch(chain, light)
    pending = np.zeros(n, np.int64)  # SMBS: trigger for the next step
    # SMBS: GetRatio's bisection, carried on across iterations: a large mutation whose ray missed
    # the caster (or failed otherwise) would repeat itself exactly from the same vertex, so the
    # next one from there starts at half the weight; an accepted one resets it
    lscale = np.ones(n)
    large_counts = dict.fromkeys(TRIGGERS[1:], 0)
    slow_n = np.zeros(n, np.int64)  # slow small steps in a row
    etas = ctx.scene.mat_ior[chain.I[:, :, MAT]]  # (N,k), of the seed's vertices
    valid = outcome == OK  # a lane converges only from a valid chain
    outcome[outcome == SIDE] = OK  # an exit below the surface is walkable, not yet valid
    act = np.flatnonzero(outcome == OK)
    if large_ok is None:
        large_ok = np.ones(n, bool)
    if cfg.smbs and cfg.tir:  # a seed whose last refraction is TIR starts with a large mutation
        tir_seed = np.flatnonzero((outcome == TIR) & large_ok)
        pending[tir_seed] = TRIG_TIR
        err[tir_seed] = np.inf
        front[tir_seed] = False
        outcome[tir_seed] = OK
        act = np.sort(np.concatenate([act, tir_seed]))
    # one kernel per iteration (kernels.walk_iterate: the acceptance of the last proposals, the
    # convergence test, the next proposal and its ray), then one per chain vertex after each
    # intersect call (trace_chain)
    cfg_t = kernel_config(ctx, cfg, types)
    lane_t = (x0, ng0, light.y, light.ys, light.yt, light.directional, etas, large_ok, ctx.obj_lo, ctx.obj_hi)
    state = (chain.F, chain.I, chain.out_dir, err, front, valid, beta, lscale, pending, slow_n, outcome, converged,
             mutations)
    new, use_large = None, np.zeros(0, bool)
    for it in range(cfg.max_iterations + 1):
        if act.size == 0:
            break

        def part(a, b, act=act, new=new, use_large=use_large, it=it):
            if new is None:
                nF = np.zeros((0, k, NF))
                nI = np.zeros((0, k, 3), np.int64)
                nst, nout = np.zeros(0, np.int64), np.zeros((0, 3))
            else:
                nF, nI, nst, nout = new.F[a:b], new.I[a:b], new.status[a:b], new.out_dir[a:b]
            return walk_iterate(act[a:b], new is not None, it == cfg.max_iterations, nF, nI, nst, nout,
                                use_large[a:b], cfg_t, lane_t, state)

        parts = lanes.run(part, act.size, ctx.tracer.threads, MIN_PART)
        for *_, counts in parts:
            for t_id in (TRIG_TIR, TRIG_BACKLIT, TRIG_SLOW):
                large_counts[TRIGGERS[t_id]] += int(counts[t_id])
        act, o, dirs, use_large = _joined([p[:4] for p in parts])
        if act.size == 0:
            break
        new = trace_chain(ctx, x0[act], o, dirs, types)
    outcome[converged] = OK
    return WalkResult(chain=chain, converged=converged, outcome=outcome, mutations=mutations, large=large_counts)
