"""Cycles' Bump Map Correction on mirrors and glass (optics.valid_reflection1).

Cycles (Material > Settings > Bump Map Correction, on by default) bends a smooth-shaded specular
closure's normal towards the geometric one wherever the mirror image of the eye's direction would
leave the surface lower than min(0.9 wi.ng, 0.01): the light then arrives along the bent mirror
image. Photons and walks cannot make those paths (they end on a ring of directions at that height),
so the paths through a bent vertex are indirect.bent_gather's alone, and the photons and walks
drop the paths Cycles' eye would have bent. Cycles itself judges the result in test_conformance
(cube_grey_reflect: the light reflected off a bevelled glass cube's outside, 0.74 of Cycles'
without the correction).
"""
import math

import numpy as np

from smbs_addon.scene import builder
from smbs_addon.shading import optics
from smbs_addon.scene import arrays as S
from smbs_addon.walks.contribution import chain_throughput
from smbs_addon.scene.geometry import Vertex


def _random_configurations(n, seed=0):
    """ng = +z, shading normals tilted up to 40 degrees, eye directions over the upper
    hemisphere with many near grazing."""
    rng = np.random.default_rng(seed)
    th, ph = rng.uniform(0, 0.7, n), rng.uniform(0, 2 * math.pi, n)
    ns = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], 1)
    z = rng.uniform(0, 1, n) ** 3
    a = rng.uniform(0, 2 * math.pi, n)
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(a), r * np.sin(a), z], 1)
    return ns, wi


def test_the_bent_normal_puts_the_mirror_image_at_the_threshold():
    """Unbent: the mirror image about n already lies at or above min(0.9 wi.ng, 0.01) (and n
    comes back unchanged). Bent: a unit normal in the plane of n and ng, turned towards ng, whose
    mirror image of wi lies exactly at that height (to 1e-9 where wi.ng >= 1e-4; closer to grazing
    the quartic's root loses digits, as Cycles' does, but the image never dips under the surface).
    About a third of these configurations bend."""
    ns, wi = _random_configurations(20000)
    ng = (0.0, 0.0, 1.0)
    bent_count = 0
    for n, w in zip(ns, wi):
        n, w = tuple(n), tuple(w)
        nb, bent = optics.valid_reflection1(ng, w, n)
        thr = min(0.9 * w[2], 0.01)
        rz = optics.reflect1(w, nb)[2]
        assert np.isfinite(nb).all()
        if not bent:
            assert nb == n and rz >= thr
            continue
        bent_count += 1
        assert abs(np.linalg.norm(nb) - 1.0) < 1e-12
        assert abs(np.linalg.det(np.array([n, ng, nb]))) < 1e-9  # in the plane of n and ng
        assert nb[2] >= n[2] - 1e-12  # turned towards ng
        assert rz >= -1e-8  # on or above the surface to rounding, at any angle
        if w[2] >= 1e-4:
            assert abs(rz - thr) < 1e-9
    assert 5000 < bent_count < 10000, bent_count


def test_bent_agrees_with_the_kernel_and_ignores_the_side():
    """optics.bent (over arrays, Cycles' flips first) is valid_reflection1's flag, whichever side
    of the surface the eye is on and whichever way the shading normal was stored."""
    ns, wi = _random_configurations(2000, seed=1)
    ng = np.broadcast_to([0.0, 0.0, 1.0], ns.shape)
    want = np.array([optics.valid_reflection1((0.0, 0.0, 1.0), tuple(w), tuple(n))[1] for n, w in zip(ns, wi)])
    assert want.any() and not want.all()
    np.testing.assert_array_equal(optics.bent(wi, ns, ng), want)
    np.testing.assert_array_equal(optics.bent(-wi, -ns, ng), want)  # the eye below: both normals flip
    np.testing.assert_array_equal(optics.bent(wi, -ns, ng), want)  # a stored normal facing away


def _mirror_tables(correct):
    b = builder.SceneBuilder("m")
    b.material("Mirror", S.CONDUCTOR, color=(0.9, 0.9, 0.9), bump_correction=correct)
    b.material("Floor", S.DIFFUSE)
    b.mesh("Sheet", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [(0, 1, 2), (0, 2, 3)], "Mirror")
    return b.build()


def test_scatter_bends_the_eye_and_drops_the_photon():
    """A mirror whose shading normal leans 20 degrees away from an eye 10 degrees above the
    surface: with the correction the eye's ray leaves at height 0.01 (bent), without it the
    mirror image dips under the surface and the eye path dies, as Cycles' would. A photon that
    arrives 0.3 degrees above the surface reflects (about the unbent normal) into an eye
    direction Cycles would bend: it dies with the correction and lives without it."""
    lean = math.radians(20)
    ns = (-math.sin(lean), 0.0, math.cos(lean))
    ng = (0.0, 0.0, 1.0)
    e = math.radians(10)
    wi = (math.cos(e), 0.0, math.sin(e))  # towards +x: the normal leans away from the eye
    beta = (1.0, 1.0, 1.0)
    for correct in (True, False):
        mats = optics.materials(_mirror_tables(correct))
        ok, d, b, bent = optics.scatter1((0.5, 0.5, 0.5), wi, ns, ng, 0, S.CONDUCTOR, mats, beta, False, False)
        if correct:
            assert ok and bent and abs(d[2] - 0.01) < 1e-12 and b == (0.9, 0.9, 0.9)
        else:
            assert not ok and not bent
    ns2 = (-math.sin(math.radians(5)), 0.0, math.cos(math.radians(5)))
    g = math.radians(0.3)
    w_light = (-math.cos(g), 0.0, math.sin(g))
    for correct in (True, False):
        mats = optics.materials(_mirror_tables(correct))
        ok, d, _, bent = optics.scatter1((0.5, 0.5, 0.5), w_light, ns2, ng, 0, S.CONDUCTOR, mats, beta, False, True)
        assert d[2] > 0.0111 or not ok
        assert ok != correct and bent == correct


def test_walked_paths_through_a_bent_vertex_carry_nothing():
    """chain_throughput: the same one-vertex chains on the mirror, with and without the
    correction, differ exactly where optics.bent says Cycles would bend the vertex's normal."""
    rng = np.random.default_rng(3)
    n = 400
    ns, wi = _random_configurations(n, seed=3)
    p = np.zeros((n, 3))
    x0 = p + wi * rng.uniform(0.5, 2.0, n)[:, None]
    ng = np.broadcast_to([0.0, 0.0, 1.0], (n, 3)).copy()
    z = np.zeros((n, 3))
    v = Vertex(p=p, ng=ng, n=ns, s=z, t=z, dn_s=z, dn_t=z, prim=np.zeros(n, np.int64), obj=np.zeros(n, np.int64),
               mat=np.zeros(n, np.int64))
    light = p + np.array([0.0, 0.0, 5.0])
    on = chain_throughput(_mirror_tables(True), "R", x0, [v], light, False)
    off = chain_throughput(_mirror_tables(False), "R", x0, [v], light, False)
    dropped = optics.bent(wi, ns, ng)
    assert 0 < dropped.sum() < n
    np.testing.assert_array_equal(on[dropped], 0.0)
    np.testing.assert_array_equal(on[~dropped], off[~dropped])
    assert (off[dropped] > 0).all()


def test_a_scene_without_the_flag_is_unchanged_and_round_trips(tmp_path):
    """Scenes built in code have no correction (an empty table); the flag survives save/load."""
    sc = _mirror_tables(False)
    assert sc.mat_bump_correction.shape == (0,)
    assert not optics.bump_correction(sc).any()
    sc = _mirror_tables(True)
    sc.save(tmp_path / "s.npz")
    back = S.Scene.load(tmp_path / "s.npz")
    np.testing.assert_array_equal(back.mat_bump_correction, [True, False])


def _leaning_mirror(correct=True):
    """A vertical mirror (the plane x = 0, facing +x, 2 m wide, 1 m tall, on the floor) whose
    shading normals all lean up by 26.6 degrees, under a square light 3 m up just in front of its
    plane: from the floor between z/2 and 4z/3 in front of a mirror point at height z the eye's
    mirror image dips behind the mirror, so Cycles bends the normal and the light arrives 0.01
    above the plane, where the light is."""
    b = builder.SceneBuilder("leaning mirror")
    floor = b.material("floor", "diffuse", color=(0.8, 0.8, 0.8))
    metal = b.material("mirror", "conductor", color=(0.9, 0.9, 0.9), bump_correction=correct)
    b.plane("Floor", (0, 0, 0), 10, floor)
    lean = np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25)
    b.mesh("Mirror", [(0, -1, 0), (0, 1, 0), (0, 1, 1), (0, -1, 1)], [(0, 1, 2, 3)], metal, normals=[lean] * 4)
    b.light("Area", "AREA", location=(0.02, 0, 3.0), target=(0.02, 0, 0), power=800, size=0.4)
    b.set_camera((3, 0, 3), (0, 0, 0), lens=40, resolution_x=32, resolution_y=24)
    return b.build()


def test_aimed_bent_paths_agree_with_cosine_sampling():
    """indirect.bent_gather's aimed first bounce (points uniform over the bending triangles, the
    density converted to solid angle, kernels._toward_triangle) against plain cosine sampling of
    the same paths (aim=False), on a mirror where every bent path has one vertex (so 'bent first'
    is 'bent'): the light at 200 floor points in front of it agrees within 4 standard errors of 8
    independent runs each (measured: aimed 8250 +- 74 with 1024 per point, cosine 8179 +- 62 with
    2048; a density off by the cosine at the triangle, or a missed visibility check, would move it
    by 10% or more)."""
    from smbs_addon.paths import gather as indirect
    from smbs_addon.trace.eye import Receivers
    from smbs_addon.baking.plan import make_plan
    from smbs_addon.trace.tracer import Tracer

    scene = _leaning_mirror()
    plan = make_plan(scene)
    tracer = Tracer(scene)
    assert indirect.bending_lights(scene, tracer, plan) == [0]
    rng = np.random.default_rng(7)
    n = 200
    p = np.stack([rng.uniform(0.05, 1.2, n), rng.uniform(-1.0, 1.0, n), np.zeros(n)], 1)
    up = np.tile([0.0, 0.0, 1.0], (n, 1))
    rc = Receivers(rx=np.zeros(n), ry=np.zeros(n), p=p, ng=up, ns=up.copy(), w_eye=up.copy(), beta=np.ones((n, 3)),
                   mat=np.zeros(n, np.int64), eye_specular=np.zeros(n, np.int64), weight=np.ones(n),
                   prior=np.zeros((n, 3), np.int64))

    st = {}

    def runs(aim, samples):
        out = []
        for k in range(8):
            rad = indirect._handoff_block(scene, tracer, plan, rc, 1000 * k + aim, 0, st, {0: None}, False,
                                          indirect.HandoffRays(samples, bent=True, aim=aim), {})
            out.append(rad.sum())
        found = st.pop("bent_paths", 0)
        return np.array(out), found

    aimed, found_a = runs(True, 1024)
    cosine, found_c = runs(False, 2048)
    assert found_a > 500 and found_c > 50, (found_a, found_c)
    se = math.hypot(aimed.std(ddof=1), cosine.std(ddof=1)) / math.sqrt(8)
    assert aimed.std(ddof=1) / math.sqrt(8) < 0.03 * aimed.mean()
    assert abs(aimed.mean() - cosine.mean()) < 4 * se, (aimed.mean(), cosine.mean(), se)
    # without the correction nothing bends and the pass has nothing to do
    plain = _leaning_mirror(correct=False)
    assert indirect.bending_lights(plain, Tracer(plain), make_plan(plain)) == []


def test_bent_receivers_are_a_random_share_of_every_cell():
    """indirect.bent_receivers (the manifold passes' receivers for the bent pass): about one in
    BENT_RECEIVER_SHARE, weighted up by as much, drawn at random. Taking every 16th instead kept
    the same film cells on every pass wherever the cells are a multiple of 16 (sample_blends'
    164 x 124) and left the others without bent light: here receivers in 1,024 cells, 8 passes
    over them, and every cell is kept on some pass, each residue mod 16 about as often."""
    from smbs_addon.paths import gather as indirect
    from smbs_addon.trace.eye import Receivers

    cells, passes = 1024, 8
    n = cells * passes
    cell = np.tile(np.arange(cells), passes)
    z = np.zeros((n, 3))
    rc = Receivers(rx=cell.astype(float), ry=np.zeros(n), p=z, ng=z, ns=z, w_eye=z, beta=np.ones((n, 3)),
                   mat=np.zeros(n, np.int64), eye_specular=np.zeros(n, np.int64), weight=np.full(n, 0.5),
                   prior=np.zeros((n, 3), np.int64))
    share = indirect.BENT_RECEIVER_SHARE
    kept = np.concatenate([indirect.bent_receivers(rc, np.random.default_rng(s)).rx for s in range(share)])
    rb = indirect.bent_receivers(rc, np.random.default_rng(99))
    assert np.all(rb.weight == 0.5 * share) and np.all(rc.weight == 0.5)  # rc itself untouched
    assert abs(len(rb.rx) - n / share) < 4 * math.sqrt(n / share)
    got = np.unique(kept.astype(int))
    assert got.size == cells  # every cell (16 draws x 8 passes: each cell missed with odds 1e-4 x 1024)
    per_residue = np.bincount(kept.astype(int) % 16, minlength=16)
    assert per_residue.min() > 0.8 * per_residue.mean()
