"""core/qmc: each film cell's scrambled Sobol' sequence is stratified (nets), uniform, independent
between cells, deterministic; StratifiedDraws hands its columns out first."""
import numpy as np
import pytest

from smbs_addon.core import qmc


def _is_net(u: np.ndarray) -> bool:
    """Whether the 2^m points u (2^m, 2) hold exactly one point in every elementary interval of
    volume 2^-m (the (0, m, 2)-net property)."""
    n = len(u)
    m = n.bit_length() - 1
    for a in range(m + 1):
        cx = np.floor(u[:, 0] * 2**a).astype(int)
        cy = np.floor(u[:, 1] * 2 ** (m - a)).astype(int)
        if len(set(zip(cx.tolist(), cy.tolist()))) != n:
            return False
    return True


@pytest.mark.parametrize("cell,seed", [(0, 0), (17, 3), (123456, 2**32 - 1)])
@pytest.mark.parametrize("m", [2, 4, 6])
def test_every_run_of_2_to_the_m_samples_is_a_net_in_each_pair(cell, seed, m):
    n = 2**m
    for start in (0, n, 5 * n):  # a cell's first samples, and those of later batches
        u = qmc.cell_points(np.full(n, cell), np.arange(start, start + n), seed)
        for pair in range(qmc.DIMS // 2):
            assert _is_net(u[:, 2 * pair:2 * pair + 2]), (cell, seed, m, start, pair)
    # a run not aligned to 2^m need not be one: the check can tell
    assert not all(_is_net(qmc.cell_points(np.full(n, cell), np.arange(s, s + n), seed)[:, :2])
                   for s in range(1, n))


def test_points_are_uniform_and_cells_independent():
    """Over 4096 cells x 16 samples: every dimension's 16 bins within 5 sigma of 1/16 of the
    points, and the cells' first points uncorrelated (|r| within 4.5 / sqrt(cells))."""
    cells, per = 4096, 16
    c = np.repeat(np.arange(cells), per)
    u = qmc.cell_points(c, np.tile(np.arange(per), cells), seed=7)
    assert u.min() >= 0.0 and u.max() < 1.0
    for d in range(qmc.DIMS):
        h = np.bincount(np.floor(u[:, d] * 16).astype(int), minlength=16)
        # stratified within cells, so the bins are steadier than a binomial's: a binomial bound holds
        assert np.all(np.abs(h - len(u) / 16) < 5 * np.sqrt(len(u) / 16)), (d, h)
    first = u[::per]  # one point per cell: independent scrambles make them independent uniforms
    r = np.corrcoef(first.T)[np.triu_indices(qmc.DIMS, 1)]
    assert np.all(np.abs(r) < 4.5 / np.sqrt(cells)), r
    # neighbouring cells' sequences are not one sequence shifted
    assert not np.allclose(u[:per], u[per:2 * per])


def test_one_seed_one_sequence():
    c, i = np.arange(1000) % 37, np.arange(1000) // 37
    a = qmc.cell_points(c, i, 11)
    assert np.array_equal(a, qmc.cell_points(c, i, 11))
    assert np.mean(a == qmc.cell_points(c, i, 12)) < 0.01


def test_sobol_first_points_are_the_textbook_ones():
    """Unscrambled (index i, not its Gray code), dimension 0 is van der Corput's and dimension 1
    Sobol's second (Joe and Kuo)."""
    x = qmc.sobol(np.arange(8)).astype(np.float64) / 2**32
    assert np.allclose(x[:, 0], [0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875])
    assert np.allclose(x[:, 1], [0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875])


def test_stratified_draws_hand_out_their_columns_then_the_generator():
    u = np.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]])
    rng = np.random.default_rng(1)
    d = qmc.StratifiedDraws(u, rng)
    assert np.array_equal(d.random(3), u[:, 0])
    assert np.array_equal(d.random(3), u[:, 1])
    third = d.random(3)
    assert np.array_equal(third, np.random.default_rng(1).random(3))
    assert d.integers(10, size=2).shape == (2,)  # other methods are the generator's
    # a draw of another size is not a light sample's: the generator's
    d2 = qmc.StratifiedDraws(u, np.random.default_rng(1))
    assert np.array_equal(d2.random(5), np.random.default_rng(1).random(5))
