"""The film: Cycles' Blackman-Harris pixel filter, splatting, batch noise estimate.

The expected values are computed independently of film.py: the window is written
here in its symmetric form h(x) = a0 + a1 cos(pi x/w) + a2 cos(2 pi x/w) + a3 cos(3 pi x/w)
(equal to Cycles' a0 - a1 cos(v) + a2 cos(2v) - a3 cos(3v) with v = 2 pi (x / 2w + 1/2)),
normalised by its integral 2 w a0.
"""
import math

import numpy as np
import pytest

from smbs_addon.trace.film import Film, blackman_harris

A = (0.35875, 0.48829, 0.14128, 0.01168)


def bh_expected(x, w):
    x = np.asarray(x, float)
    h = sum(a * np.cos(k * math.pi * x / w) for k, a in enumerate(A))
    return np.where(np.abs(x) <= w, h / (2.0 * w * A[0]), 0.0)


@pytest.mark.parametrize("w", [0.5, 1.5, 3.0])
def test_filter_integrates_to_one(w):
    # composite Simpson on [-w, w] (the window is smooth there); error ~ (h/w)^4
    n = 20000
    x = np.linspace(-w, w, n + 1)
    y = blackman_harris(x, w)
    integral = (x[1] - x[0]) / 3 * (y[0] + y[-1] + 4 * y[1:-1:2].sum() + 2 * y[2:-1:2].sum())
    assert integral == pytest.approx(1.0, abs=1e-12)
    # and nothing outside
    outside = np.linspace(w + 1e-9, w + 5, 1000)
    assert np.all(blackman_harris(outside, w) == 0) and np.all(blackman_harris(-outside, w) == 0)


@pytest.mark.parametrize("w", [0.5, 1.5, 3.0])
def test_filter_support_is_exactly_the_width(w):
    """Cycles builds the table with width * 2, so the radius equals the filter width."""
    eps = 1e-12 * w
    inside = blackman_harris(np.array([-w, -w + eps, w - eps, w]), w)
    assert np.all(inside > 0)
    # the window's edge value: (a0 - a1 + a2 - a3) / (2 w a0), tiny but not zero
    edge = (A[0] - A[1] + A[2] - A[3]) / (2 * w * A[0])
    np.testing.assert_allclose(inside, edge, rtol=1e-9)
    assert np.all(blackman_harris(np.array([-w - eps, w + eps]), w) == 0)
    # peak at 0 is 1 / (2 w a0) (the a_k sum to 1)
    assert blackman_harris(np.array([0.0]), w)[0] == pytest.approx(1.0 / (2 * w * A[0]), rel=1e-14)


@pytest.mark.parametrize("w", [0.5, 1.5, 3.0])
def test_filter_matches_independent_formula(w):
    x = np.linspace(-w - 1, w + 1, 2001)
    np.testing.assert_allclose(blackman_harris(x, w), bh_expected(x, w), rtol=1e-12, atol=1e-15)


def splat_one(W, H, w, rx, ry, region=None):
    film = Film(W, H, filter_width=w, region=region)
    film.splat(np.array([rx]), np.array([ry]), np.array([[1.0, 2.0, -3.0]]))
    film.end_batch()
    return film.image


def expected_weights(W, H, w, rx, ry):
    """Weights of every pixel centre (i + 0.5, j + 0.5), by brute force over the image."""
    cx = np.arange(W) + 0.5
    cy = np.arange(H) + 0.5
    return np.outer(bh_expected(cy - ry, w), bh_expected(cx - rx, w))


@pytest.mark.parametrize("w", [0.5, 1.5, 3.0])
@pytest.mark.parametrize("rx,ry", [(10.3, 7.71), (10.5, 8.5), (0.2, 0.9), (19.95, 14.01), (-0.7, 3.3),
                                   (21.2, 16.4)])
def test_single_splat_equals_filter_mass_inside_image(w, rx, ry):
    W, H = 20, 15
    img = splat_one(W, H, w, rx, ry)
    exp = expected_weights(W, H, w, rx, ry)
    for c, v in enumerate((1.0, 2.0, -3.0)):
        np.testing.assert_allclose(img[..., c], v * exp, rtol=1e-12, atol=1e-15)
    assert img[..., 0].sum() == pytest.approx(exp.sum(), rel=1e-12, abs=1e-15)


def test_total_away_from_borders_closed_form():
    """Sampling the window at unit spacing aliases only the harmonics k with k / (2w)
    an integer: for w = 3 none (2w = 6 consecutive samples sum to exactly 1), for
    w = 1.5 the k = 3 term gives 1 - (a3 / a0) cos(2 pi f) per axis, f the sub-pixel
    position. When a pixel centre falls exactly on the edge +-w (f = 0 for w = 1.5,
    f = 1/2 for w = 3) there is one sample more: the window's edge value."""
    W, H = 30, 30
    edge = lambda w: (A[0] - A[1] + A[2] - A[3]) / (2 * w * A[0])  # noqa: E731

    def per_axis(f, w):
        if w == 3.0:
            return 1.0 + (edge(w) if f == 0.5 else 0.0)
        return 1.0 - A[3] / A[0] * math.cos(2 * math.pi * f) + (edge(w) if f == 0.0 else 0.0)

    for rx, ry in [(15.0, 15.0), (15.25, 14.6), (15.5, 15.5), (14.9, 15.13), (15.5, 15.75)]:
        fx, fy = rx % 1.0, ry % 1.0
        for w in (1.5, 3.0):
            total = splat_one(W, H, w, rx, ry)[..., 0].sum()
            assert total == pytest.approx(per_axis(fx, w) * per_axis(fy, w), rel=1e-13), (w, rx, ry)
    # off the edges, w = 3 is exactly normalised; w = 1.5 is off by up to a3/a0 = 3.3 %
    assert splat_one(W, H, 3.0, 15.3, 14.2)[..., 0].sum() == pytest.approx(1.0, abs=1e-13)


def test_splat_respects_region():
    W, H = 20, 15
    region = (5, 12, 3, 9)  # x0, x1, y0, y1 (y from the top)
    img = splat_one(W, H, 1.5, 5.2, 8.7, region=region)
    exp = expected_weights(W, H, 1.5, 5.2, 8.7)
    mask = np.zeros((H, W), bool)
    mask[3:9, 5:12] = True
    np.testing.assert_allclose(img[..., 0], np.where(mask, exp, 0.0), rtol=1e-12, atol=1e-15)
    assert np.count_nonzero(img[..., 0]) == np.count_nonzero(np.where(mask, exp, 0.0))


@pytest.mark.parametrize("w", [0.5, 1.5, 2.0, 3.0])
@pytest.mark.parametrize("region", [None, (5, 12, 3, 9)])
def test_frame_share_is_what_a_splat_leaves_in_the_region(w, region):
    """Film.frame_share against the independent window, summed over the region's pixels: inside,
    on the edges, and in the filter's margin, where a splat can land wholly outside (share 0)."""
    W, H = 20, 15
    x0, x1, y0, y1 = region or (0, W, 0, H)
    mask = np.zeros((H, W), bool)
    mask[y0:y1, x0:x1] = True
    rng = np.random.default_rng(2)
    rx = np.concatenate([rng.uniform(x0 - w - 1, x1 + w + 1, 60), [x0 - w - 0.01, x1 + w + 0.01]])
    ry = np.concatenate([rng.uniform(y0 - w - 1, y1 + w + 1, 60), [0.5 * (y0 + y1)] * 2])
    share = Film(W, H, filter_width=w, region=region).frame_share(rx, ry)
    exp = np.array([expected_weights(W, H, w, x, y)[mask].sum() for x, y in zip(rx, ry)])
    np.testing.assert_allclose(share, exp, rtol=1e-12, atol=1e-15)
    assert share[-2] == share[-1] == 0.0 and (share > 0.5).any() and ((share > 0) & (share < 0.5)).any()


def test_many_splats_add_up():
    rng = np.random.default_rng(1)
    W, H, w = 16, 12, 1.5
    n = 300
    rx, ry = rng.uniform(-2, W + 2, n), rng.uniform(-2, H + 2, n)
    rgb = rng.normal(size=(n, 3))
    film = Film(W, H, filter_width=w)
    film.splat(rx, ry, rgb)
    film.end_batch()
    exp = sum(rgb[i][None, None, :] * expected_weights(W, H, w, rx[i], ry[i])[..., None] for i in range(n))
    np.testing.assert_allclose(film.image, exp, rtol=1e-10, atol=1e-12)


def test_noise_estimate_is_variance_of_the_batch_mean():
    """Batch b puts value x_b into pixel (i, j) (a width-0.5 filter splatted at a
    pixel centre reaches that pixel only, with weight 1/a0 per axis, 1/a0^2 in all).
    The image is the mean of the batch values and the variance the sample variance / B."""
    rng = np.random.default_rng(5)
    W, H, B = 4, 3, 9
    film = Film(W, H, filter_width=0.5)
    centres_x, centres_y = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    values = rng.normal(loc=2.0, scale=0.7, size=(B, H * W, 3))
    for b in range(B):
        film.splat(centres_x.ravel(), centres_y.ravel(), values[b])
        film.end_batch()
    x = values / A[0] ** 2  # what each batch really holds
    assert film.batches == B
    np.testing.assert_allclose(film.image, x.mean(0).reshape(H, W, 3), rtol=1e-13)
    np.testing.assert_allclose(film.variance, (x.var(0, ddof=1) / B).reshape(H, W, 3), rtol=1e-10)


def test_noise_estimate_two_batches_and_constant_values():
    film = Film(1, 1, filter_width=0.5)
    for v in (1.0, 3.0):
        film.splat(np.array([0.5]), np.array([0.5]), np.array([[v * A[0] ** 2, 0.0, 0.0]]))
        film.end_batch()
    # batch values 1 and 3: mean 2, sample variance 2, variance of the mean 1
    assert film.image[0, 0, 0] == pytest.approx(2.0, rel=1e-14)
    assert film.variance[0, 0, 0] == pytest.approx(1.0, rel=1e-12)
    assert film.variance[0, 0, 1] == 0.0
    one = Film(2, 2)
    one.splat(np.array([1.0]), np.array([1.0]), np.array([[1.0, 1.0, 1.0]]))
    one.end_batch()
    assert np.all(one.variance == 0)  # fewer than two batches: no estimate


def test_noise_estimate_statistically_honest():
    """Over many pixels (independent experiments), the estimated variance of the
    mean averages to the true variance sigma^2 / B."""
    rng = np.random.default_rng(9)
    W, H, B, sigma = 50, 40, 6, 0.3
    film = Film(W, H, filter_width=0.5)
    cx, cy = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    for _ in range(B):
        vals = rng.normal(1.0, sigma, size=(W * H, 3)) * A[0] ** 2
        film.splat(cx.ravel(), cy.ravel(), vals)
        film.end_batch()
    est = film.variance.mean()
    true = sigma**2 / B
    # the mean of 6000 chi-square(5)/5 variables: relative standard deviation sqrt(2/5/6000)
    assert est == pytest.approx(true, rel=4 * math.sqrt(2 / 5 / 6000))


@pytest.mark.parametrize("w", [0.5, 1.5, 3.0])
def test_a_splat_shared_over_threads_is_one_threads_bit_for_bit(w):
    """Film.splat of SPLAT_SPLIT samples or more: each thread adds to rows of its own, so every
    pixel's sum is made in the samples' order, as on one thread: the same image, bit for bit
    (2, 3 and 7 threads; rows fewer than threads; a region; textured parts alike)."""
    from smbs_addon.trace.film import SPLAT_SPLIT

    rng = np.random.default_rng(5)
    W, H, n = 40, 30, 3 * SPLAT_SPLIT
    rx, ry = rng.uniform(-3, W + 3, n), rng.uniform(-3, H + 3, n)
    rgb = rng.lognormal(0.0, 3.0, size=(n, 3))
    albedo = np.where(rng.random((n, 1)) < 0.5, rng.random((n, 3)), 0.0)
    for region in (None, (5, 33, 3, 27), (0, W, 11, 13)):
        films = [Film(W, H, filter_width=w, region=region, textured=True, threads=t) for t in (1, 2, 3, 7)]
        for f in films:
            f.splat(rx, ry, rgb, albedo)
            f.splat(rx[:100], ry[:100], rgb[:100])  # below SPLAT_SPLIT: one call
            f.end_batch()
        for f in films[1:]:
            assert np.array_equal(f.image, films[0].image)
            for a, b in zip(f.textured_parts(), films[0].textured_parts()):
                assert np.array_equal(a, b)
        x0, x1, y0, y1 = region or (0, W, 0, H)
        assert np.count_nonzero(films[0].image[..., 0]) == (x1 - x0) * (y1 - y0)  # every pixel of the region


def test_a_batchs_sums_on_the_threads_are_one_threads():
    """Film.end_batch adds a batch to the sums in parts of pixels on the threads (a film of 2.3
    END_BATCH_PART pixels: 1, 2 and 3 parts): the image, the variance and the batches' luminances
    are one thread's, bit for bit, and the next batch starts from zero."""
    from smbs_addon.trace.film import END_BATCH_PART

    W, H = 600, END_BATCH_PART * 23 // 10 // 600
    rng = np.random.default_rng(8)
    films = [Film(W, H, filter_width=1.5, threads=t) for t in (1, 2, 3)]
    for b in range(3):
        n = 5000
        rx, ry, rgb = rng.uniform(0, W, n), rng.uniform(0, H, n), rng.lognormal(0, 2, (n, 3))
        for f in films:
            f.splat(rx, ry, rgb)
            f.end_batch(float(b))
            assert not f._cur.any()
    for f in films[1:]:
        assert np.array_equal(f.image, films[0].image) and np.array_equal(f.variance, films[0].variance)
        assert all(np.array_equal(a, b) for a, b in zip(f.batch_luminance, films[0].batch_luminance))
    assert films[0].image.any() and len(films[0].batch_luminance) == 3
