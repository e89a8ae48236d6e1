"""The embree tracer with float64 hit records (smbs_addon/tracer.py).

Exact answers come from rational arithmetic (fractions.Fraction) or from the
interpolation formulas worked by hand; derivatives from central differences of
an independent implementation of the interpolation.
"""
import math
from fractions import Fraction

import numpy as np
import pytest

from smbs_addon.scene.builder import SceneBuilder
from smbs_addon.trace.tracer import Tracer


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def exact_plane_hit(o, d, v0, ng):
    """o + t d on the plane (v0, ng), in exact rational arithmetic, rounded once."""
    F = [Fraction(float(x)) for x in ng]
    num = sum((Fraction(float(a)) - Fraction(float(b))) * c for a, b, c in zip(v0, o, F))
    den = sum(Fraction(float(a)) * c for a, c in zip(d, F))
    t = num / den
    return np.array([float(Fraction(float(a)) + t * Fraction(float(b))) for a, b in zip(o, d)])


# ------------------------------------------------------------------ precision
@pytest.fixture(scope="module")
def far_triangle():
    """One big triangle on a tilted plane some 2e5 units from the origin (float32
    spacing there is 1/64)."""
    C = np.array([1.0e5 + 0.123, -2.0e5 + 0.456, 3.0e4 + 0.789])
    n = unit([0.3, -0.5, 0.8])
    s = unit(np.cross(n, [0.0, 0.0, 1.0]))
    t = np.cross(n, s)
    L = 50.0
    V = np.array([C - L * s - L * t, C + 2 * L * s - L * t, C - L * s + 2 * L * t])
    b = SceneBuilder("far")
    m = b.material("m", "diffuse")
    b.mesh("Tri", V, [[0, 1, 2]], m)
    scene = b.build()
    return scene, Tracer(scene, threads=1), C, s, t, n


@pytest.mark.parametrize("dist", [100.0, 1.0, 0.05])
def test_far_tilted_plane_hits_are_float64_accurate(far_triangle, dist):
    scene, tr, C, s, t, n = far_triangle
    rng = np.random.default_rng(int(dist * 100))
    N = 400
    target = C + rng.uniform(-20, 20, (N, 1)) * s + rng.uniform(-20, 20, (N, 1)) * t
    d = unit(rng.normal(size=(N, 3)))
    d = np.where((d @ n)[:, None] > 0, -d, d)
    d = np.where(np.abs(d @ n)[:, None] < 0.2, -n, d)
    o = target - dist * d
    h = tr.intersect(o, d)
    assert h.hit.all()
    v0, ng = tr.v[0, 0], tr.ng[0]
    mag = np.abs(C).max()
    exact = np.array([exact_plane_hit(o[i], d[i], v0, ng) for i in range(0, N, 8)])
    err = np.abs(h.p[::8] - exact).max() / mag
    assert err < 1e-9, f"float64 hit positions off by {err:.2g} of the coordinates"
    np.testing.assert_allclose(h.t[::8], np.linalg.norm(exact - o[::8], axis=1), rtol=1e-9, atol=1e-9 * mag)
    # embree's float32 distance alone would not be: its error is ~1e-7 of the coordinates
    _, t32 = tr._run(o, d, None, "INTERSECT")
    err32 = np.abs(o[::8] + t32[::8, None] * d[::8] - exact).max() / mag
    assert err32 > 1e-8


def test_spawned_rays_do_not_hit_their_own_surface(far_triangle):
    """Rays leaving the far triangle on either side, from spawn()ed origins, never
    re-hit it (the only geometry), even at grazing angles."""
    scene, tr, C, s, t, n = far_triangle
    rng = np.random.default_rng(2)
    N = 20000
    p = C + rng.uniform(-20, 20, (N, 1)) * s + rng.uniform(-20, 20, (N, 1)) * t
    d = unit(rng.normal(size=(N, 3)))
    d[:100] = unit(s + 1e-3 * n * np.sign(rng.normal(size=(100, 1))))  # grazing
    ng = np.broadcast_to(tr.ng[0], (N, 3))
    o = tr.spawn(p, ng, d)
    off = (o - p) @ tr.ng[0]
    side = np.sign(d @ tr.ng[0])
    np.testing.assert_allclose(off, side * tr.eps, rtol=1e-6)
    h = tr.intersect(o, d)
    assert not h.hit.any(), f"{h.hit.sum()} self-intersections"


def test_spawn_offsets_to_the_side_the_ray_leaves_on():
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.plane("P", (0, 0, 0), 2, m)
    tr = Tracer(b.build(), threads=1)
    p = np.zeros((4, 3))
    ng = np.tile([0.0, 0.0, 1.0], (4, 1))
    d = unit([[0, 0, 1], [1, 0, 1], [0, 0, -1], [1, 1, -0.1]])
    o = tr.spawn(p, ng, d)
    np.testing.assert_array_equal(o[:, :2], 0.0)
    np.testing.assert_allclose(o[:, 2], [tr.eps, tr.eps, -tr.eps, -tr.eps], rtol=1e-15)
    assert tr.eps > 0
    # flipping the normal does not change where the origin goes
    np.testing.assert_allclose(tr.spawn(p, -ng, d), o, rtol=1e-15)


# ------------------------------------------------------------ shading normals
CORNER_N = unit([[0.2, -0.1, 1.0], [-0.4, 0.3, 0.8], [0.1, 0.6, 0.9]])


@pytest.fixture(scope="module")
def smooth_triangle():
    b = SceneBuilder("smooth")
    m = b.material("m", "diffuse")
    V = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.1], [0.3, 1.5, -0.2]])
    uv = np.array([[0.1, 0.2], [0.9, 0.3], [0.2, 0.8]])
    b.mesh_corners("Smooth", V[None], CORNER_N[None], uv[None], [m], smooth=True)
    scene = b.build()
    return scene, Tracer(scene, threads=1), V, uv


BARY = [(1 / 3, 1 / 3), (0.1, 0.2), (0.7, 0.25), (0.05, 0.9), (0.0, 0.5), (0.5, 0.5)]


def test_shading_normals_interpolate(smooth_triangle):
    scene, tr, V, uv = smooth_triangle
    b = np.array(BARY)
    pts = V[0] + b[:, :1] * (V[1] - V[0]) + b[:, 1:] * (V[2] - V[0])
    ng = unit(np.cross(V[1] - V[0], V[2] - V[0]))
    o = pts + 3.0 * ng + np.array([0.01, -0.02, 0.0])
    d = unit(pts - o)
    h = tr.intersect(o, d)
    assert h.hit.all()
    np.testing.assert_allclose(h.p, pts, atol=1e-12)
    np.testing.assert_allclose(h.b, b, atol=1e-12)
    np.testing.assert_allclose(h.ng, np.broadcast_to(ng, h.ng.shape), atol=1e-15)
    for i, (b1, b2) in enumerate(BARY):
        b0 = 1 - b1 - b2
        raw = [b0 * CORNER_N[0][k] + b1 * CORNER_N[1][k] + b2 * CORNER_N[2][k] for k in range(3)]
        length = math.sqrt(sum(x * x for x in raw))
        np.testing.assert_allclose(h.ns[i], [x / length for x in raw], atol=1e-14)
    # at the corners the corner normal itself
    nb = tr.shading_normal(np.zeros(3, np.int64), np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    np.testing.assert_allclose(nb, CORNER_N, atol=1e-15)


def test_shading_normal_is_not_flipped_towards_the_geometric_normal():
    """Like Cycles' triangle_smooth_normal: corner normals against the winding stay so."""
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # winding normal +Z
    b.mesh_corners("Flipped", V[None], np.tile([0.0, 0.0, -1.0], (1, 3, 1)), None, [m])
    tr = Tracer(b.build(), threads=1)
    h = tr.intersect(np.array([[0.2, 0.2, 1.0]]), np.array([[0.0, 0.0, -1.0]]))
    assert h.hit[0]
    np.testing.assert_array_equal(h.ng[0], [0, 0, 1])
    np.testing.assert_array_equal(h.ns[0], [0, 0, -1])


def independent_frame(V, uv, nc, u, v):
    """p(u, v) and the normalised interpolated normal, solving for barycentrics directly."""
    M = np.array([[uv[1, 0] - uv[0, 0], uv[2, 0] - uv[0, 0]],
                  [uv[1, 1] - uv[0, 1], uv[2, 1] - uv[0, 1]]])
    b1, b2 = np.linalg.solve(M, np.array([u - uv[0, 0], v - uv[0, 1]]))
    p = V[0] + b1 * (V[1] - V[0]) + b2 * (V[2] - V[0])
    n = (1 - b1 - b2) * nc[0] + b1 * nc[1] + b2 * nc[2]
    return p, n / np.linalg.norm(n), (b1, b2)


def test_differentials_match_finite_differences(smooth_triangle):
    scene, tr, V, uv = smooth_triangle
    eps = 1e-6
    for b1, b2 in BARY:
        u0, v0 = uv[0] + b1 * (uv[1] - uv[0]) + b2 * (uv[2] - uv[0])
        _, n0, bb = independent_frame(V, uv, CORNER_N, u0, v0)
        assert bb == pytest.approx((b1, b2), abs=1e-12)
        dif = tr.differentials(np.array([0]), np.array([[b1, b2]]))
        pu = [independent_frame(V, uv, CORNER_N, u0 + s * eps, v0) for s in (1, -1)]
        pv = [independent_frame(V, uv, CORNER_N, u0, v0 + s * eps) for s in (1, -1)]
        dpdu, dndu = (pu[0][0] - pu[1][0]) / (2 * eps), (pu[0][1] - pu[1][1]) / (2 * eps)
        dpdv, dndv = (pv[0][0] - pv[1][0]) / (2 * eps), (pv[0][1] - pv[1][1]) / (2 * eps)
        np.testing.assert_allclose(dif["dpdu"][0], dpdu, atol=1e-8)
        np.testing.assert_allclose(dif["dpdv"][0], dpdv, atol=1e-8)
        np.testing.assert_allclose(dif["dndu"][0], dndu, atol=1e-7)
        np.testing.assert_allclose(dif["dndv"][0], dndv, atol=1e-7)
        np.testing.assert_allclose(dif["n"][0], n0, atol=1e-14)
        # the derivative of a unit normal is perpendicular to it
        assert abs(dif["dndu"][0] @ n0) < 1e-12 and abs(dif["dndv"][0] @ n0) < 1e-12


def test_differentials_without_uvs_use_the_triangle_edges():
    """Degenerate UVs (all equal) fall back to u, v = barycentrics: dp/du = e1, dp/dv = e2."""
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    V = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    b.mesh_corners("T", V[None], CORNER_N[None], np.full((1, 3, 2), 0.5), [m])
    tr = Tracer(b.build(), threads=1)
    dif = tr.differentials(np.array([0]), np.array([[0.2, 0.3]]))
    np.testing.assert_allclose(dif["dpdu"][0], V[1] - V[0], atol=1e-15)
    np.testing.assert_allclose(dif["dpdv"][0], V[2] - V[0], atol=1e-15)
    assert np.all(np.isfinite(dif["dndu"])) and np.all(np.isfinite(dif["dndv"]))


# --------------------------------------------------------------- occlusion
@pytest.fixture(scope="module")
def floor_and_blocker():
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.plane("Floor", (0, 0, 0), 10, m)
    b.plane("Behind", (0, 0, 8), 10, m)
    return Tracer(b.build(), threads=1)


def test_occluded_respects_tmax(floor_and_blocker):
    tr = floor_and_blocker
    o = np.tile([0.1, 0.2, 5.0], (6, 1))
    down, up = np.array([0, 0, -1.0]), np.array([0, 0, 1.0])
    d = np.array([down, down, down, up, up, down])
    tmax = np.array([4.9, 5.1, np.inf, 2.9, 3.1, 5.0 - 1e-4])
    assert tr.occluded(o, d, tmax).tolist() == [False, True, True, False, True, False]
    # a surface behind the origin never occludes
    assert not tr.occluded(np.array([[0.1, 0.2, 5.0]]), np.array([[0.0, 0.0, 1.0]]), np.array([2.0]))[0]
    # intersect agrees: closest hit at t = 5, and tmax cuts it off
    h = tr.intersect(o[:2], d[:2], np.array([4.9, 5.1]))
    assert h.hit.tolist() == [False, True]
    assert h.t[1] == pytest.approx(5.0, abs=1e-12) and h.prim[0] == -1 and h.t[0] == np.inf


def test_empty_scene_hits_nothing():
    b = SceneBuilder()
    tr = Tracer(b.build(), threads=1)
    o, d = np.zeros((3, 3)), np.tile([0, 0, 1.0], (3, 1))
    assert not tr.occluded(o, d, np.full(3, 10.0)).any()
    h = tr.intersect(o, d)
    assert not h.hit.any() and np.all(h.prim == -1)


# ---------------------------------------------------------------- threads
def test_threads_give_identical_results():
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.uv_sphere("Ball", (0, 0, 0), 1.0, m, segments=48, rings=24)
    b.plane("Floor", (0, 0, -1.5), 6, m)
    scene = b.build()
    rng = np.random.default_rng(11)
    N = 100_000
    o = rng.uniform(-2, 2, (N, 3)) + np.array([0, 0, 3.0])
    d = unit(rng.uniform(-2.5, 2.5, (N, 3)) - o)  # aimed at the ball and the floor
    h1 = Tracer(scene, threads=1).intersect(o, d)
    tr2 = Tracer(scene, threads=2)
    h2 = tr2.intersect(o, d)
    assert 0.2 < h1.hit.mean() < 0.9
    for f in ("hit", "prim", "t", "p", "ng", "ns", "b"):
        assert np.array_equal(getattr(h1, f), getattr(h2, f)), f
    tmax = rng.uniform(0, 5, N)
    assert np.array_equal(Tracer(scene, threads=1).occluded(o, d, tmax), tr2.occluded(o, d, tmax))


def test_embree_from_the_kernels_answers_as_embreex_does():
    """smbs_addon/embree.py builds the scene with embree's C API and casts from compiled code;
    embreex's own run, on a scene embreex builds from the same triangles, must give the same
    primitives and float32 distances bit for bit (closest hits without and with a segment
    length, and occlusion), on rays that hit, graze and miss a ball and a floor."""
    import embreex.mesh_construction as emc
    import embreex.rtcore_scene as ers

    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.uv_sphere("Ball", (0, 0, 0), 1.0, m, segments=48, rings=24)
    b.plane("Floor", (0, 0, -1.5), 6, m)
    scene = b.build()
    tr = Tracer(scene, threads=2)
    es = ers.EmbreeScene()
    emc.TriangleMesh(es, np.ascontiguousarray(scene.tri_vertices, dtype=np.float32))
    rng = np.random.default_rng(12)
    N = 200_000
    o = rng.uniform(-2, 2, (N, 3)) + np.array([0, 0, 3.0])
    d = unit(rng.uniform(-2.5, 2.5, (N, 3)) - o)
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    prim, t = tr.cast(o, d)
    ref = es.run(o32, d32, output=1)
    assert 0.2 < (prim >= 0).mean() < 0.9
    assert np.array_equal(prim, ref["primID"]) and np.array_equal(t[prim >= 0], ref["tfar"][prim >= 0])
    tmax = rng.uniform(0, 6, N)
    occl = tr.occluded(o, d, tmax)
    ref_occl = es.run(o32, d32, dists=tmax.astype(np.float32), query="OCCLUDED") >= 0
    assert np.array_equal(occl, ref_occl) and 0.1 < occl.mean() < 0.9
    h = tr.intersect(o, d, tmax)
    ref_t = es.run(o32, d32, dists=tmax.astype(np.float32), output=1)
    assert np.array_equal(h.prim, ref_t["primID"])
    assert tr.rays_cast == 3 * N


def test_rays_aimed_at_the_edges_of_a_closed_mesh_do_not_pass_through():
    """embree.Scene keeps RTC_SCENE_FLAG_ROBUST: from inside a closed UV sphere, rays aimed at
    points on its triangles' shared edges all hit it. Built without the flag, embree lets 6% of
    them through (5,156 of 80,000 from the centre, bench/embree_flags.py) for rays 13-33% faster:
    a walk or a photon inside glass would leave it unrefracted."""
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    b.uv_sphere("Ball", (0.1, 0.2, 0.3), 1.0, m, segments=64, rings=32)
    scene = b.build()
    tv = scene.tri_vertices
    rng = np.random.default_rng(1)
    n = 20_000
    tri, e, a = rng.integers(0, len(tv), n), rng.integers(0, 3, n), rng.random(n)[:, None]
    q = tv[tri, e] * (1 - a) + tv[tri, (e + 1) % 3] * a
    tr = Tracer(scene, threads=1)
    for src in ([0.1, 0.2, 0.3], [0.4, 0.1, 0.5]):
        o = np.broadcast_to(np.array(src), q.shape)
        prim, _ = tr.cast(o, unit(q - o))
        assert (prim < 0).sum() == 0


# ------------------------------------------------------------- degenerates
def test_degenerate_triangles_and_zero_normals_give_no_nan():
    b = SceneBuilder()
    m = b.material("m", "diffuse")
    tris = np.array([
        [[0, 0, 0], [1, 0, 0], [2, 0, 0]],  # collinear
        [[0, 1, 0], [0, 1, 0], [0, 1, 0]],  # a point
        [[-1, -1, 0], [1, -1, 0], [0, 1, 0]],  # fine triangle, zero corner normals
        [[-1, -1, 1], [1, -1, 1], [0, 1, 1]],  # corner normals that cancel at the centroid
        [[0, 0, 2], [1e-9, 0, 2], [0, 1e-9, 2]],  # tiny
    ], float)
    normals = np.zeros((5, 3, 3))
    normals[3] = [[0, 0, 1], [0, 0, -1], [0, 0, 0]]
    normals[4] = [[0, 0, 1]] * 3
    uvs = np.zeros((5, 3, 2))  # degenerate UVs everywhere
    b.mesh_corners("Bad", tris, normals, uvs, [m])
    tr = Tracer(b.build(), threads=1)
    rng = np.random.default_rng(3)
    N = 5000
    o = np.concatenate([rng.uniform(-1.5, 1.5, (N, 3)) + [0, 0, 4], rng.uniform(-1.5, 1.5, (N, 3)) - [0, 0, 4]])
    d = unit(np.concatenate([np.tile([0, 0, -1.0], (N, 1)), np.tile([0, 0, 1.0], (N, 1))])
             + rng.normal(scale=0.2, size=(2 * N, 3)))
    # plus rays aimed straight at the degenerate ones and at the centroid of the cancelling one
    aim = np.array([[1.0, 0, 0], [0, 1, 0], [0, -1 / 3, 1], [0.0, -1 / 3, 0]])
    o = np.concatenate([o, aim + [0.0, 0.0, 3.0]])
    d = np.concatenate([d, np.tile([0, 0, -1.0], (4, 1))])
    h = tr.intersect(o, d)
    assert h.hit.sum() > 1000
    for f in ("t", "p", "ng", "ns", "b"):
        v = getattr(h, f)
        assert not np.isnan(v).any(), f
    assert np.all(np.isfinite(h.p[h.hit]))
    # hit shading normals are unit (geometric normal where the corner normals give none)
    np.testing.assert_allclose(np.linalg.norm(h.ns[h.hit], axis=1), 1.0, atol=1e-12)
    zero_n = h.hit & (h.prim == 2)
    assert zero_n.any()
    np.testing.assert_allclose(h.ns[zero_n], h.ng[zero_n], atol=0)
    # the direct helpers on every triangle, degenerate ones included
    prim = np.repeat(np.arange(5), 4)
    bary = np.tile([[1 / 3, 1 / 3], [0.0, 0.0], [0.5, 0.5], [0.2, 0.1]], (5, 1))
    assert np.all(np.isfinite(tr.barycentrics(prim, tris[prim].mean(1))))
    assert np.all(np.isfinite(tr.shading_normal(prim, bary)))
    dif = tr.differentials(prim, bary)
    for k, v in dif.items():
        assert np.all(np.isfinite(v)), k
    # the cancelling triangle at its centroid of n0, n1 (b = (1/2, 0)) falls back to ng
    np.testing.assert_allclose(tr.shading_normal(np.array([3]), np.array([[0.5, 0.0]]))[0], [0, 0, 1], atol=0)
