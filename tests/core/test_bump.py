"""Bumped mirrors and glass (bump.py): the finer mesh and Cycles' Bump node on its corner normals."""
import numpy as np
import pytest

from smbs_addon.scene import bump

# a non-planar quad as two triangles, vertex 3 raised
CO = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.5]])
TV = np.array([[0, 1, 2], [0, 2, 3]])


def _face_normals(v):
    return np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])


@pytest.mark.parametrize("n", [1, 2, 3, 8])
def test_subdivide_keeps_the_surface_and_shares_every_edge(n):
    normals = np.tile([0.0, 0.0, 1.0], (2, 3, 1))
    co, tv, _, _, parent = bump.subdivide(TV, CO, normals, None, n)
    assert len(tv) == 2 * n * n
    v, v0 = co[tv], CO[TV]
    f, f0 = _face_normals(v), _face_normals(v0)
    # the same area per parent triangle, wound the same way, every point made once
    np.testing.assert_allclose(np.bincount(parent, 0.5 * np.linalg.norm(f, axis=1)),
                               0.5 * np.linalg.norm(f0, axis=1), rtol=1e-12)
    assert np.all((f * f0[parent]).sum(1) > 0)
    assert len(np.unique(co, axis=0)) == len(co) == len(np.unique(tv))
    # watertight: the quad's border has 4 n edges, every other edge two triangles
    e = np.sort(np.concatenate([tv[:, [0, 1]], tv[:, [1, 2]], tv[:, [2, 0]]]), axis=1)
    _, count = np.unique(e, axis=0, return_counts=True)
    assert np.sum(count == 1) == 4 * n and np.all(count <= 2)


def test_subdivide_interpolates_corner_normals_and_uvs_in_their_triangle():
    normals = np.array([[[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]], [[0, 0, 1.0]] * 3])
    uvs = np.array([[[0.0, 0], [1, 0], [1, 1]], [[0.0, 0], [1, 1], [0, 1]]])
    co, tv, n2, uv2, parent = bump.subdivide(TV, CO, normals, uvs, 4)
    # every corner's normal and uv are the parent's barycentric mix at that corner's point
    for t in range(len(tv)):
        p = parent[t]
        e1, e2 = CO[TV[p, 1]] - CO[TV[p, 0]], CO[TV[p, 2]] - CO[TV[p, 0]]
        for c in range(3):
            b = np.linalg.lstsq(np.stack([e1, e2], 1), co[tv[t, c]] - CO[TV[p, 0]], rcond=None)[0]
            w = np.array([1 - b.sum(), b[0], b[1]])
            np.testing.assert_allclose(n2[t, c], w @ normals[p], atol=1e-12)
            np.testing.assert_allclose(uv2[t, c], w @ uvs[p], atol=1e-12)


def _plane(n=6):
    co, tv, normals, _, _ = bump.subdivide(np.array([[0, 1, 2], [0, 2, 3]]),
                                           np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]),
                                           np.tile([0.0, 0.0, 1.0], (2, 3, 1)), None, n)
    return co, tv, normals


def _cycles(N, grad, distance, strength):
    """svm node_set_bump with exact differentials: normalize(N - distance grad), mixed by strength."""
    nb = N - distance * grad
    nb /= np.linalg.norm(nb, axis=-1, keepdims=True)
    nb = strength * nb + (1 - strength) * N
    return nb / np.linalg.norm(nb, axis=-1, keepdims=True)


@pytest.mark.parametrize("distance,strength", [(0.5, 1.0), (0.5, 0.3), (-0.5, 1.0), (2.0, 0.8)])
def test_bend_is_cycles_bump_for_a_linear_height(distance, strength):
    co, tv, normals = _plane()
    g = np.array([0.7, -0.4, 0.0])
    h = co @ g + 0.25
    T = len(tv)
    out, back = bump.bend(co[tv], normals, tv, h, np.full(T, distance), np.full(T, strength))
    want = _cycles(np.array([0.0, 0.0, 1.0]), g, distance, strength)
    np.testing.assert_allclose(out, np.broadcast_to(want, out.shape), atol=1e-12)
    # from behind Cycles bends the flipped normal by the same term: -normalize(-N - d g) as an outward normal
    want_back = -_cycles(np.array([0.0, 0.0, -1.0]), g, distance, strength)
    np.testing.assert_allclose(back, np.broadcast_to(want_back, back.shape), atol=1e-12)


def test_bend_takes_the_gradient_along_a_tilted_surface_and_leaves_unbumped_triangles():
    co, tv, normals = _plane()
    R = np.array([[1.0, 0, 0], [0, np.cos(0.6), -np.sin(0.6)], [0, np.sin(0.6), np.cos(0.6)]])
    co_w = co @ R.T
    N = np.array([0.0, 0.0, 1.0]) @ R.T
    n_w = np.broadcast_to(N, normals.shape).copy()
    h = 0.3 * co[:, 0] - 0.5 * co[:, 1]  # linear on the surface: its gradient lies in it
    T = len(tv)
    strength = np.where(np.arange(T) % 2 == 0, 1.0, 0.0)
    out, back = bump.bend(co_w[tv], n_w, tv, h, np.full(T, 0.4), strength)
    grad = np.array([0.3, -0.5, 0.0]) @ R.T
    np.testing.assert_allclose(out[0::2], np.broadcast_to(_cycles(N, grad, 0.4, 1.0), out[0::2].shape),
                               atol=1e-12)
    np.testing.assert_array_equal(out[1::2], n_w[1::2])
    np.testing.assert_array_equal(back[1::2], n_w[1::2])


def test_bend_of_a_curved_height_converges_with_the_mesh():
    """H = x^2 + sin(3y): the normal at the vertices from the area-weighted gradients tends to
    Cycles' (at the grid's inner vertices the error falls as the cell size squared)."""
    errs = []
    for n in (8, 16, 32):
        co, tv, normals = _plane(n)
        h = co[:, 0] ** 2 + np.sin(3 * co[:, 1])
        T = len(tv)
        out, _ = bump.bend(co[tv], normals, tv, h, np.full(T, 0.3), np.ones(T))
        p = co[tv]
        grad = np.stack([2 * p[..., 0], 3 * np.cos(3 * p[..., 1]), 0 * p[..., 0]], -1)
        want = _cycles(normals, grad, 0.3, 1.0)
        inner = np.all(np.abs(p[..., :2]) < 1 - 1e-9, axis=-1)
        errs.append(np.abs(out - want)[inner].max())
    assert errs[1] < 0.3 * errs[0] and errs[2] < 0.3 * errs[1] and errs[2] < 3e-3, errs  # second order


def test_segments_aim_at_the_target_count():
    assert bump.segments(2) == 256 and bump.segments(2) ** 2 * 2 == bump.TARGET_TRIANGLES
    assert bump.segments(bump.TARGET_TRIANGLES) == 1 and bump.segments(10 ** 7) == 1
    assert bump.segments(1, target=10 ** 9) == bump.MAX_SEGMENTS


def test_targets_share_the_budget_by_area():
    assert list(bump.targets([36.0])) == [bump.TARGET_TRIANGLES]
    t = bump.targets([1.0] * 20)
    assert np.all(t == bump.BUDGET_TRIANGLES // 20) and t.sum() <= bump.BUDGET_TRIANGLES
    t = bump.targets([3.0, 1.0, 0.0], budget=4000)
    assert list(t) == [3000, 1000, 0]


# ------------------------------------------------------------------ the normals met from behind
def _sheet(back=True):
    """A bumped unit sheet (two triangles, +Z up, corner normals tilted towards -X) whose normals met
    from behind tilt towards +X (Cycles' bump, bump.bend)."""
    from smbs_addon.scene.builder import SceneBuilder

    b = SceneBuilder("sheet")
    m = b.material("glass", "dielectric", ior=1.5)
    V = np.array([[[-1.0, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1.0, -1, 0], [1, 1, 0], [-1, 1, 0]]])
    front = np.broadcast_to(np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0), (2, 3, 3))
    behind = np.broadcast_to(np.array([0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0), (2, 3, 3))
    b.mesh_corners("Sheet", V, front, None, [m, m], caster=True, smooth=True,
                   tri_normals_back=behind if back else None)
    return b.build(), front[0, 0], behind[0, 0]


def test_a_ray_from_behind_meets_the_normals_met_from_behind():
    """Tracer.intersect (kernels.shading_normal1): a ray running along the geometric normal takes
    Scene.tri_normals_back, one against it tri_normals; without them, tri_normals either way."""
    from smbs_addon.trace.tracer import Tracer

    sc, front, behind = _sheet()
    tr = Tracer(sc, threads=1)
    o = np.array([[0.1, 0.2, 1.0], [0.1, 0.2, -1.0]])
    d = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
    h = tr.intersect(o, d)
    np.testing.assert_allclose(h.ns, [front, behind], atol=1e-14)
    sc1, _, _ = _sheet(back=False)
    h1 = Tracer(sc1, threads=1).intersect(o, d)
    np.testing.assert_allclose(h1.ns, [front, front], atol=1e-14)
    assert sc1.tri_normals_back.shape == (0, 3, 3)


def test_normals_from_behind_keep_through_save_and_load_and_are_checked(tmp_path):
    from smbs_addon.core.errors import SceneError
    from smbs_addon.scene.arrays import Scene

    sc, _, behind = _sheet()
    sc.save(tmp_path / "s.npz")
    again = Scene.load(tmp_path / "s.npz")
    np.testing.assert_array_equal(again.tri_normals_back, sc.tri_normals_back)
    sc.tri_normals_back = sc.tri_normals_back[:1]
    with pytest.raises(SceneError, match="tri_normals_back"):
        sc.validate()


def test_a_walk_through_a_bumped_sheet_takes_each_sides_normals():
    """A refraction (T) through the sheet, walked from below (the receiver's side, as Cycles' eye path
    goes) meets it from behind and refracts about the normals met from behind; from above, about the
    front's. The walk's vertex records the normal it used (kernels._lane_vertex)."""
    from types import SimpleNamespace

    from smbs_addon.walks import walk
    from smbs_addon.trace.tracer import Tracer

    sc, front, behind = _sheet()
    ctx = SimpleNamespace(tracer=Tracer(sc, threads=1), casters=np.ones(1, bool), count=lambda key, n: None)
    for z, want in ((-1.0, behind), (1.0, front)):
        x0 = np.array([[0.1, 0.2, z]])
        d = np.array([[0.0, 0.0, -np.sign(z)]])
        chain = walk.propagate(ctx, x0, np.array([[0.0, 0.0, np.sign(z)]]), d, "T")
        assert chain.status[0] == 0, chain.status
        np.testing.assert_allclose(chain.verts[0].n[0], want, atol=1e-12)
