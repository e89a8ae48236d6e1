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

from . import scene as S
from .constraints import ANGLE_DIFF, LightEnd, block_solve, blocks, specular_map
from .geometry import Vertex, vertex_from_hits
from .large_mutation import large_direction
from .vec import dot, normalize

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
    backlit: bool = True  # SMBS trigger 2: light on the wrong side of x1 for its interaction
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
    """k vertices over N lanes plus each lane's status."""

    verts: list
    status: np.ndarray
    out_dir: np.ndarray  # (N,3) direction leaving the last vertex

    def take(self, idx) -> "Chain":
        return Chain([v.take(idx) for v in self.verts], self.status[idx], self.out_dir[idx])


def _empty_vertex(n):
    z3 = np.zeros((n, 3))
    zi = np.zeros(n, np.int64)
    return Vertex(z3, z3.copy(), z3.copy(), z3.copy(), z3.copy(), z3.copy(), z3.copy(), zi, zi.copy(), zi.copy())


def _put(dst: Vertex, idx, src: Vertex):
    for f in dst.__dataclass_fields__:
        getattr(dst, f)[idx] = getattr(src, f)


def propagate(ctx, x0, ng0, d, types: str, target=None) -> Chain:
    """Trace x0 -> d and follow the chain's reflections/refractions (shading normals).

    Every vertex must be a specular caster; a T vertex must be glass. The
    geometric normal must agree with the interaction (reflection stays on its
    side, refraction crosses), else the chain is rejected (SIDE)."""
    scene, tracer = ctx.scene, ctx.tracer
    n = len(x0)
    k = len(types)
    verts = [_empty_vertex(n) for _ in range(k)]
    status = np.full(n, OK, np.int64)
    out = np.zeros((n, 3))
    act = np.arange(n)
    o = tracer.spawn(x0, ng0, d)
    # aim from the offset origin itself, so the hit lands on the proposed point
    dirs = d.copy() if target is None else normalize(target - o)
    prev = x0
    for j, kind in enumerate(types):
        if act.size == 0:
            break
        h = tracer.intersect(o, dirs, exact_origin=None if j == 0 else prev)
        ctx.count("rays_walk", len(o))
        miss = ~h.hit
        prim = np.where(h.hit, h.prim, 0)
        mat = scene.tri_material[prim]
        mkind = scene.mat_kind[mat]
        obj = scene.tri_object[prim]
        bad = np.full(len(act), OK, np.int64)
        bad[~ctx.casters[obj]] = NOT_CASTER
        need = (mkind == S.DIELECTRIC) if kind == "T" else ((mkind == S.CONDUCTOR) | (mkind == S.DIELECTRIC))
        bad[~need & (bad == OK)] = WRONG_MATERIAL
        bad[miss] = MISS
        v = vertex_from_hits(scene, tracer, prim, h.p, h.b)
        # from the true previous vertex, not the offset ray origin: the chain stays exact
        w_in = normalize(prev - v.p)
        w_out, okm = specular_map(kind, w_in, v.n, scene.mat_ior[mat])
        bad[(~okm) & (bad == OK)] = TIR if j == k - 1 else TIR_INNER
        cin, cout = dot(w_in, v.ng), dot(w_out, v.ng)
        # Cycles: the geometric normal picks the side, the shading normal (oriented to the
        # geometric one: v.n's sign is free here) must face w_in on it, and the new direction
        # must leave on the side the interaction calls for
        side_ok = ((cin * cout > 0) if kind == "R" else (cin * cout < 0)) & \
            (dot(w_in, v.n) * dot(v.n, v.ng) * cin > 0)
        bad[(~side_ok) & (bad == OK)] = SIDE if j == k - 1 else SIDE_INNER
        status[act] = bad
        good = bad == OK
        if j == k - 1:
            # keep the last vertex of a chain whose exit is TIR: SMBS can mutate from it; and of
            # one whose exit dips below the geometric surface (a shading normal leaning away, as
            # on a normal-mapped mirror): every walk goes on from it, as SMS does from any seed
            # on the caster, and converges only once the exit is valid
            _put(verts[j], act[bad == TIR], v.take(bad == TIR))
            side = bad == SIDE
            _put(verts[j], act[side], v.take(side))
            out[act[side]] = normalize(w_out[side])
        _put(verts[j], act[good], v.take(good))
        act = act[good]
        w_out = normalize(w_out[good])
        out[act] = w_out
        o = tracer.spawn(v.p[good], v.ng[good], w_out)
        dirs = w_out
        prev = v.p[good]
    return Chain(verts, status, out)


def end_mismatch(chain: Chain, light: LightEnd):
    """|w_o' - w_o| at the last vertex: the propagated direction against the
    direction to the light end; and whether it points to the light's side."""
    k = len(chain.verts)
    if light.directional:
        to_light = light.y
    else:
        to_light = normalize(light.y - chain.verts[k - 1].p)
    diff = chain.out_dir - to_light
    return np.sqrt(dot(diff, diff)), dot(chain.out_dir, to_light) > 0


def backlit(types: str, x0, chain: Chain, light: LightEnd):
    """SMBS trigger 2 at x1: for a reflection, x0 and the light lie on different
    sides of x1's surface; for a refraction, on the same side."""
    v = chain.verts[0]
    to_light = light.y if light.directional else light.y - v.p
    a = dot(x0 - v.p, v.n) > 0
    b = dot(to_light, v.n) > 0
    return (a != b) if types[0] == "R" else (a == b)


@dataclass
class WalkResult:
    chain: Chain
    converged: np.ndarray
    outcome: np.ndarray
    mutations: np.ndarray  # proposals made per lane (small + large)
    large: dict = field(default_factory=dict)  # trigger name -> count


def newton_walk(ctx, cfg: WalkConfig, types: str, x0, ng0, light: LightEnd, chain: Chain,
                large_ok: np.ndarray | None = None) -> WalkResult:
    """Walk every lane's chain to the light end. Lanes whose seed failed keep
    their seed outcome. large_ok (N,) bool: lanes allowed SMBS's large mutations
    (the rest walk as plain SMS)."""
    n = len(x0)
    k = len(types)
    chain = Chain([Vertex(*(getattr(v, f).copy() for f in v.__dataclass_fields__)) for v in chain.verts],
                  chain.status.copy(), chain.out_dir.copy())
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
    etas_all = [ctx.scene.mat_ior[v.mat] for v in chain.verts]
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
    max_step = cfg.max_step * ctx.scale
    for it in range(cfg.max_iterations + 1):
        if act.size == 0:
            break
        done = (err[act] < cfg.threshold) & front[act] & valid[act]
        converged[act[done]] = True
        act = act[~done]
        if it == cfg.max_iterations or act.size == 0:
            outcome[act] = MAX_ITER
            break
        ch = chain.take(act)
        x0a, ng0a, la = x0[act], ng0[act], light.take(act)
        etas = [e[act] for e in etas_all]
        # --- small mutation: Newton step of x1 from the block-tridiagonal system
        C, A, B, D, okc = blocks(cfg.form, types, x0a, ch.verts, etas, la)
        delta, oks = block_solve(A, B, D, C[..., None])
        step = -(delta[:, 0, 0, 0][:, None] * ch.verts[0].s + delta[:, 0, 1, 0][:, None] * ch.verts[0].t)
        ls = np.sqrt(dot(step, step))
        step *= np.minimum(1.0, max_step / np.maximum(ls, 1e-300))[:, None]
        p = ch.verts[0].p + beta[act][:, None] * step
        d = normalize(p - x0a)
        use_large = np.zeros(act.size, bool)
        if cfg.smbs:
            trig = pending[act].copy()
            if cfg.backlit:
                bl = backlit(types, x0a, ch, la) & (trig == NONE)
                trig[bl] = TRIG_BACKLIT
            want = (trig != NONE) & large_ok[act]
            if want.any():
                lo = ctx.obj_lo[ch.verts[0].obj]
                hi = ctx.obj_hi[ch.verts[0].obj]
                dl, okl = large_direction(types, ch.verts, etas, la, x0a, lo, hi, lscale[act])
                use_large = want & okl
                d = np.where(use_large[:, None], dl, d)
                for t_id in (TRIG_TIR, TRIG_BACKLIT, TRIG_SLOW):
                    large_counts[TRIGGERS[t_id]] += int((use_large & (trig == t_id)).sum())
            pending[act] = NONE
        singular = ~(okc & oks) & ~use_large
        outcome[act[singular]] = SINGULAR
        keep = ~singular
        act, d, use_large = act[keep], d[keep], use_large[keep]
        p = np.where(use_large[:, None], x0[act] + d, p[keep])
        if act.size == 0:
            break
        mutations[act] += 1
        new = propagate(ctx, x0[act], ng0[act], d, types, target=p)
        e_new, f_new = end_mismatch(new, light.take(act))
        okp = (new.status == OK) | (new.status == SIDE)
        accept = okp & (use_large | (e_new < err[act]))
        # a large mutation that ends in total internal reflection still moves the chain (its last
        # vertex is kept, as for a TIR seed): the next one bisects on from there instead of
        # repeating the same rejected proposal until the walk counts as stuck
        moved_tir = use_large & (new.status == TIR) & cfg.tir
        accept |= moved_tir
        e_new[moved_tir], f_new[moved_tir] = np.inf, False
        pending[act[moved_tir]] = TRIG_TIR
        acc = act[accept]
        for j in range(k):
            _put(chain.verts[j], acc, new.verts[j].take(accept))
        chain.out_dir[acc] = new.out_dir[accept]
        if cfg.smbs and cfg.slow:
            # trigger 3 on the last small mutation's proposal, kept or not: a rejected one
            # (the mismatch grew, ratio > 1 > tau) is the slowest progress of all; waiting for
            # beta to shrink below min_beta instead lost 9-13% of all walks to local minima
            slow = okp & ~use_large & (e_new > cfg.tau * err[act])
            slow_n[act] = np.where(slow, slow_n[act] + 1, 0)
            fire = slow & (slow_n[act] >= cfg.slow_run)
            slow_n[act[fire]] = 0
            pending[act[fire]] = TRIG_SLOW
        err[acc], front[acc] = e_new[accept], f_new[accept]
        valid[acc] = new.status[accept] == OK
        beta[acc] = np.minimum(1.0, 2.0 * beta[acc])
        beta[act[accept & use_large]] = 1.0  # Algorithm 2, line 7: a large mutation restarts the step
        lscale[act[accept & use_large]] = 1.0
        lscale[act[use_large & ~accept]] *= 0.5
        rej = act[~accept]
        beta[rej] *= 0.5
        if cfg.smbs and cfg.tir and cfg.tir_rejected:
            pending[act[(new.status == TIR) & ~accept]] = TRIG_TIR
        stuck = rej[beta[rej] < cfg.min_beta]  # the step had to shrink too far: give up
        outcome[stuck] = MAX_ITER
        act = np.setdiff1d(act, stuck, assume_unique=True)
    outcome[converged] = OK
    return WalkResult(chain=chain, converged=converged, outcome=outcome, mutations=mutations, large=large_counts)
