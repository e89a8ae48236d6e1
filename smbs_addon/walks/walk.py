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

from ..shading.light_samples import LightEnd
from ..scene.geometry import vertex_view
from ..core import embree, lanes
from ..kernels import chain, records, walk
from ..kernels.chain import end_mismatch as _mismatch_rows  # (end_mismatch's argument chain hides the module)
from ..kernels.records import (
    ChainRows, LightRows, NF, SeedRays, TRIGGERS, TRIG_BACKLIT, TRIG_SLOW, TRIG_TIR, WalkLanes, WalkSettings,
    WalkState)



HALF_VECTOR, ANGLE_DIFF = "hv", "ad"  # the constraint forms: MNEE's half-vector, SMS's and SMBS's angle difference
MAX_HALVINGS = 10  # a below 2^-10 counts as 0: keep the current direction


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
    beta0: float = 1.0  # the first small step's share of the Newton step
    stall_window: int = 0  # walks without large mutations give up (outcome "stalled") when the
    stall_factor: float = 1.0  # last stall_window steps shrank the mismatch by less than this
    stall_from: int = 0  # factor, from this step on; 0: never


# The give-up rule of BakeSettings.stall_stop (WalkConfig.stall_*): a walk whose last 4 steps
# shrank its mismatch by less than 10% stops, from its 6th step on. On the glass ball (256^2,
# SMS, primary walks) the walks that ran to max_iterations mostly sat at a mismatch of about
# 1.6 rad for all 20 steps (no solution near them): the rule cut the T T walks' steps by 15%
# and their successes by 1.8%. With BakeSettings.first_step 1/8 (the published full first
# step was rejected in 91% of the walks that went on to converge there, the second in 71%):
# Newton steps per success T T 14.9 -> 10.6, R 40 -> 26; the ring's R 17.2 -> 13.5. The
# unbiased estimator stays unbiased (its Bernoulli trials walk by the same rules); they would
# shift the energy of MNEE and the biased estimator, which keep the published walk
STALL = dict(stall_window=4, stall_factor=0.9, stall_from=6)


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


WALK_BLOCK = 2048  # lanes per block of newton_walk and propagate (lanes.blocks)


def walk_geometry(ctx) -> records.Geometry:
    """The scene as the kernels trace chains through it (kernels/chain.py's trace_lane)."""
    return ctx.tracer.kernel_geometry(ctx.casters)


def count_rays(ctx, counts) -> None:
    ctx.count("rays_seed", counts[embree.KINDS + records.RAYS_SEED])
    ctx.count("rays_walk", counts[embree.KINDS + records.RAYS_WALK])


def propagate(ctx, x0, ng0, d, types: str, want_obj=None) -> Chain:
    """Trace x0 -> d and follow the chain's reflections/refractions (shading normals): seed
    chains, their rays counted as seed rays.

    Every vertex must be a specular caster; a T vertex must be glass. The geometric normal
    must agree with the interaction (reflection stays on its side, refraction crosses), else
    the chain is rejected (SIDE). want_obj (N,): a chain whose first vertex lies on another
    object ends as SEED_OBJECT (None: any caster)."""
    n, k = len(x0), len(types)
    F, I = np.zeros((n, k, NF)), np.zeros((n, k, 3), np.int64)
    status, out = np.zeros(n, np.int64), np.zeros((n, 3))
    x0, ng0, d = (np.ascontiguousarray(a, np.float64) for a in (x0, ng0, d))
    want = np.full(n, -1, np.int64) if want_obj is None else np.ascontiguousarray(want_obj, np.int64)
    kinds, geo, tracer = records.chain_kinds(types), walk_geometry(ctx), ctx.tracer

    def part(a, b):
        rt = tracer.rays()
        counts = chain.trace_lanes(rt, kinds, x0[a:b], ng0[a:b], SeedRays(d[a:b], want[a:b]), geo, tracer.eps,
                                   ChainRows(F[a:b], I[a:b], status[a:b], out[a:b]))
        tracer.cast_by_kernel(rt, counts)
        return counts

    counts = sum(lanes.blocks(part, n, WALK_BLOCK, tracer.threads, whole=True), embree.counters())
    count_rays(ctx, counts)
    return Chain(F, I, status, out)


def end_mismatch(chain: Chain, light: LightEnd):
    """|w_o' - w_o| at the last vertex: the propagated direction against the
    direction to the light end; and whether it points to the light's side."""
    return _mismatch_rows(np.arange(len(chain.F)), chain.F, chain.out_dir, light.y, light.directional)


def backlit(cfg: WalkConfig, types: str, x0, chain: Chain, light: LightEnd) -> np.ndarray:
    """SMBS trigger 2 per lane, as the walk tests it (cfg.backlit_vertex): at chain vertex j,
    for a reflection the vertex before it (x0 for j = 0) and the light lie on different sides
    of its surface; for a refraction, on the same side."""
    return walk.backlit_lanes(records.chain_kinds(types), _backlit_at(cfg.backlit_vertex, len(types)),
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


def kernel_config(ctx, cfg: WalkConfig, types: str) -> WalkSettings:
    """The walk's settings as the kernels take them (kernels/walk.py's _walk_lane)."""
    return WalkSettings(hv=cfg.form == HALF_VECTOR, kinds=records.chain_kinds(types), smbs=cfg.smbs, tir=cfg.tir,
                        backlit=cfg.backlit, slow=cfg.slow, tir_rejected=cfg.tir_rejected,
                        backlit_at=_backlit_at(cfg.backlit_vertex, len(types)), tau=cfg.tau, slow_run=cfg.slow_run,
                        min_beta=cfg.min_beta, threshold=cfg.threshold, max_step=cfg.max_step * ctx.scale,
                        eps=ctx.tracer.eps, max_halvings=MAX_HALVINGS, max_iterations=cfg.max_iterations,
                        beta0=float(cfg.beta0), stall_window=int(cfg.stall_window),
                        stall_factor=float(cfg.stall_factor), stall_from=int(max(cfg.stall_from, cfg.stall_window)))


def newton_walk(ctx, cfg: WalkConfig, types: str, x0, ng0, light: LightEnd, chain: Chain | None = None,
                large_ok: np.ndarray | None = None, seed: tuple | None = None) -> WalkResult:
    """Walk every lane's chain to the light end, from its seed chain (chain) or from a seed ray
    (seed = (directions, want_obj), as propagate takes them), traced in the same kernel call
    as the walk. Lanes whose seed failed keep their seed outcome. large_ok (N,) bool: lanes
    allowed SMBS's large mutations (the rest walk as plain SMS).

    walk.walk_lanes walks each lane from its seed to its outcome, casting its rays itself;
    the lanes are cut into blocks of WALK_BLOCK that the threads take in turn (lanes.blocks).
    Lanes walk independently of each other: the result does not depend on the cut."""
    n, k = len(x0), len(types)
    if chain is None:
        F, I = np.zeros((n, k, NF)), np.zeros((n, k, 3), np.int64)
        outcome, out_dir = np.zeros(n, np.int64), np.zeros((n, 3))
        d = np.ascontiguousarray(seed[0], np.float64)
        want = np.full(n, -1, np.int64) if seed[1] is None else np.ascontiguousarray(seed[1], np.int64)
    else:
        F, I, outcome, out_dir = chain.F.copy(), chain.I.copy(), chain.status.copy(), chain.out_dir.copy()
        d, want = np.zeros((n, 3)), np.full(n, -1, np.int64)
    x0, ng0, ly, lys, lyt = (np.ascontiguousarray(a, np.float64) for a in (x0, ng0, light.y, light.ys, light.yt))
    large_ok = np.ones(n, bool) if large_ok is None else np.ascontiguousarray(large_ok, bool)
    etas = np.zeros((n, k))
    state = WalkState(F=F, I=I, out_dir=out_dir, err=np.zeros(n), front=np.zeros(n, bool), valid=np.zeros(n, bool),
                      beta=np.ones(n), lscale=np.ones(n), pending=np.zeros(n, np.int64), slow_n=np.zeros(n, np.int64),
                      outcome=outcome, converged=np.zeros(n, bool), mutations=np.zeros(n, np.int64))
    cfg_t, geo, tracer = kernel_config(ctx, cfg, types), walk_geometry(ctx), ctx.tracer

    def part(a, b):
        rt = tracer.rays()
        lane = WalkLanes(x0[a:b], ng0[a:b], LightRows(ly[a:b], lys[a:b], lyt[a:b], light.directional), etas[a:b],
                         large_ok[a:b], ctx.obj_lo, ctx.obj_hi)
        large, counts = walk.walk_lanes(rt, chain is not None, SeedRays(d[a:b], want[a:b]), cfg_t, geo, lane,
                                        WalkState(*(x[a:b] for x in state)))
        tracer.cast_by_kernel(rt, counts)
        return large, counts

    parts = lanes.blocks(part, n, WALK_BLOCK, tracer.threads, whole=True)
    large = sum((p[0] for p in parts), np.zeros(4, np.int64))
    count_rays(ctx, sum((p[1] for p in parts), embree.counters()))
    converged, mutations = state.converged, state.mutations
    return WalkResult(chain=Chain(F, I, outcome.copy(), out_dir), converged=converged, outcome=outcome,
                      mutations=mutations, large={TRIGGERS[t]: int(large[t]) for t in (TRIG_TIR, TRIG_BACKLIT,
                                                                                      TRIG_SLOW)})
