"""KLD sampling's numba kernel against the NumPy reference: the same draws, bit for bit."""

import math

import numpy as np
import pytest

from filters.localization import kld_kernels
from filters.localization.mcl import MCLConfig, MonteCarloLocalizer
from tests.test_mcl import symmetric_room


def _localizer(fast: bool, seed: int, **kw) -> MonteCarloLocalizer:
    cfg = MCLConfig(kld=True, fast_path=fast, global_particles_per_m2=50.0, **kw)
    return MonteCarloLocalizer(symmetric_room(), cfg, rng=np.random.default_rng(seed))


def _cloud(kind: str, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Particle poses and normalised weights of a few shapes the filter meets."""
    if kind == "uniform":
        p = np.column_stack([rng.uniform(0, 10, n), rng.uniform(0, 5, n), rng.uniform(-np.pi, np.pi, n)])
        w = rng.random(n)
    elif kind == "peaked":  # one tight cluster holding nearly all the weight, some zero weights
        p = np.column_stack([rng.normal(3, 0.2, n), rng.normal(2, 0.2, n), rng.normal(0, 0.1, n)])
        w = np.exp(-20 * rng.random(n))
        w[rng.random(n) < 0.2] = 0.0
    elif kind == "seam":  # headings straddling +-pi, poses left of and below the origin, bin edges
        p = np.column_stack([rng.normal(-0.5, 0.5, n), rng.normal(-0.25, 0.5, n), np.pi - rng.random(n) * 0.2])
        p[::7, 2] = -np.pi
        p[::5, 0] = 0.5 * rng.integers(-3, 3, p[::5].shape[0])
        w = rng.random(n) ** 4
    else:  # "two": two look-alike clusters, as in a symmetric room
        half = n // 2
        a = rng.normal([2.0, 1.0, 0.5], [0.3, 0.3, 0.2], (half, 3))
        b = rng.normal([8.0, 4.0, 0.5 - np.pi], [0.3, 0.3, 0.2], (n - half, 3))
        p = np.vstack([a, b])
        w = rng.random(n)
    return np.ascontiguousarray(p), w / w.sum()


@pytest.mark.parametrize("kind", ["uniform", "peaked", "seam", "two"])
@pytest.mark.parametrize("n", [1, 37, 2000])
def test_kld_draw_equals_reference(kind, n):
    for seed in range(4):
        rng = np.random.default_rng(100 * seed + n)
        poses, w = _cloud(kind, rng, n)
        out = []
        for fast in (True, False):
            mcl = _localizer(fast, seed, n_particles=None, min_particles=50, max_particles=5000)
            mcl._poses = poses
            idx = mcl._kld_indices(w)
            out.append((idx, mcl.rng.random()))  # the next draw: both consumed the same uniforms
        assert out[0][0].dtype == out[1][0].dtype == np.int64
        assert out[0][0].tobytes() == out[1][0].tobytes(), (kind, n, seed)
        assert out[0][1] == out[1][1]


def test_kld_draw_stops_at_the_bound_and_the_minimum():
    """A single bin needs one particle by Fox's bound, so the minimum decides; a uniform cloud
    over many bins needs more than the minimum."""
    rng = np.random.default_rng(0)
    for lo in (1, 30):
        for fast in (True, False):
            mcl = _localizer(fast, 0, n_particles=None, min_particles=lo, max_particles=4000)
            mcl._poses = np.tile([[1.1, 1.1, 0.01]], (500, 1))
            assert mcl._kld_indices(np.full(500, 1 / 500)).size == lo
    mcl = _localizer(True, 0, n_particles=None, min_particles=30, max_particles=4000)
    poses, w = _cloud("uniform", rng, 4000)
    mcl._poses = poses
    n = mcl._kld_indices(w).size
    assert 30 < n <= 4000


def test_bound_table_holds_the_reference_values():
    """The kernel's table of Fox's bound equals the bound computed on any array of bin counts."""
    mcl = _localizer(True, 0, n_particles=None, max_particles=20000)
    table = mcl._kld_bound_table(20000)
    rng = np.random.default_rng(1)
    for size in (1, 7, 16, 17, 1000, 14001):
        k = np.cumsum(rng.random(size) < 0.6)
        assert mcl.kld_required(k).tobytes() == table[k].tobytes()
    assert table[0] == table[1] == 1.0
    for k in (2, 10, 1000):  # Fox (2003), Eq. 12, written out independently
        a = 2.0 / (9.0 * (k - 1))
        want = (k - 1) / (2.0 * mcl.config.kld_epsilon) * (1.0 - a + math.sqrt(a) * mcl.config.kld_z) ** 3
        assert math.isclose(table[k], want, rel_tol=1e-12)


def test_cdf_search_equals_searchsorted_on_ties():
    """Pointers that equal CDF entries exactly, repeated entries (zero weights) and the last entry
    forced to 1 below a rounded-up sum: the kernel's search returns ``np.searchsorted``'s index for every
    pointer a uniform draw can be (``[0, 1)``: an entry at or above 1 is never a pointer)."""
    rng = np.random.default_rng(2)
    for _ in range(20):
        w = rng.random(50) * (rng.random(50) < 0.7)
        w[0] = 1.0
        w /= w.sum()
        cdf = np.cumsum(w)
        cdf[-1] = 1.0
        u = np.concatenate([cdf[:-1], rng.random(50), [0.0, np.nextafter(1.0, 0.0)]])
        u = u[u < 1.0]
        want = np.minimum(np.searchsorted(cdf, u, side="right"), w.size - 1)
        poses = np.zeros((w.size, 3))
        idx = np.empty(u.size, dtype=np.int64)
        bound = np.full(u.size + 1, np.inf)  # never met: every pointer is searched
        extent = kld_kernels.dense_extent(poses, 0.5, 0.2, 10**6)
        assert kld_kernels.kld_draw(poses, cdf, u, 1, bound, 0.5, 0.2, extent, idx) == u.size
        np.testing.assert_array_equal(idx, want)


@pytest.mark.parametrize("spread", ["huge", "wide", "non-finite"])
def test_absurd_clouds_fall_back_to_the_reference(spread):
    """Clouds whose bins would not fit a dense table (coordinates near the int64 limit, or spanning
    more bins than the table may hold) take the reference path: the same draws, no crash."""
    rng = np.random.default_rng(3)
    poses, w = _cloud("uniform", rng, 300)
    if spread == "huge":
        poses[::2, 0] = -(2.0**61)
        poses[1::2, 0] = 2.0**61 + 512.0
    elif spread == "wide":
        poses[:, 0] = rng.uniform(-1e6, 1e6, 300)
    assert kld_kernels.dense_extent(poses, 0.5, math.radians(10.0), 8_000_000) is None or spread == "non-finite"
    if spread == "non-finite":
        poses[5, 1] = np.nan
        assert kld_kernels.dense_extent(poses, 0.5, math.radians(10.0), 8_000_000) is None
        return  # the reference's np.floor(nan).astype(int) is undefined too: only the guard is checked
    out = []
    for fast in (True, False):
        mcl = _localizer(fast, 7, n_particles=None, min_particles=50, max_particles=5000)
        mcl._poses = poses
        out.append(mcl._kld_indices(w))
    assert out[0].tobytes() == out[1].tobytes()


def _retry_case(one_sequence: bool, fast: bool, seed: int = 5) -> tuple[MonteCarloLocalizer, np.ndarray]:
    """A localizer and weights whose first ``max(2 N, 4 min_particles)`` draws cannot meet Fox's bound: 100 particles
    in 100 bins, each as likely (the bound for 100 bins is about 450 draws), ``max_particles`` 2000."""
    mcl = _localizer(fast, seed, n_particles=None, min_particles=10, max_particles=2000, kld_one_sequence=one_sequence)
    mcl._poses = np.column_stack([np.arange(100) * 1.0 + 0.25, np.full(100, 0.25), np.zeros(100)])
    return mcl, np.full(100, 0.01)


@pytest.mark.parametrize("fast", [True, False])
def test_kld_one_sequence_goes_on_where_the_first_draws_stopped(fast):
    """With ``kld_one_sequence`` the set is what one sequence of uniforms gives, stopped where Fox's bound is first met
    (Fox 2003); without it (every env before SemReloc-v22) the retry draws ``max_particles`` uniforms from scratch."""
    for seed in range(3):
        for one in (True, False):
            mcl, w = _retry_case(one, fast, seed)
            lo, hi = mcl.kld_bounds
            m = max(2 * w.size, 4 * lo)
            assert m < hi and mcl.kld_required(np.array([100]))[0] > m  # the first m draws cannot meet the bound
            stream = np.random.default_rng(seed).random(m + hi)
            u = stream[:hi] if one else stream[m : m + hi]
            idx = mcl._kld_indices(w)
            assert idx.tolist() == _fox(mcl, w, u, lo)
            assert m < idx.size < hi


def _fox(mcl: MonteCarloLocalizer, w: np.ndarray, u: np.ndarray, lo: int) -> list[int]:
    """Fox's KLD sampling written out draw by draw (an oracle apart from the filter's code): each uniform picks a
    particle by the weights' CDF; stop at the first count that meets the bound for the bins occupied and ``lo``."""
    c = mcl.config
    cdf = np.cumsum(w)
    picked, bins = [], set()
    for x in u:
        i = min(int(np.searchsorted(cdf, x, side="right")), w.size - 1)
        picked.append(i)
        p = mcl._poses[i]
        bins.add(
            (
                math.floor(p[0] / c.kld_bin_xy_m),
                math.floor(p[1] / c.kld_bin_xy_m),
                math.floor((p[2] + np.pi) / c.kld_bin_theta_rad),
            )
        )
        if len(picked) >= lo and len(picked) >= mcl.kld_required(np.array([len(bins)]))[0]:
            break
    return picked


@pytest.mark.parametrize("fast", [True, False])
def test_kld_one_sequence_keeps_fox_s_distribution_of_the_set_size(fast):
    """The outside audit's case: 9 bins, one of weight 0.006, ``min_particles`` 50, so the first ``m = 200`` draws
    meet the bound only if the rare bin was hit late or never. The retry's fresh sequence then stops at or below ``m``
    more often than one sequence can go on to (Fox's set sizes): P(n <= 200) 0.54 against 0.32 over 400 seeds, median
    186 against 202. With one sequence the first ``m`` draws are the set's first ``m`` particles."""
    poses = np.column_stack([np.arange(9) * 1.0 + 0.25, np.full(9, 0.25), np.zeros(9)])
    w = np.full(9, (1 - 0.006) / 8)
    w[8] = 0.006
    small = {}
    for one in (True, False):
        mcl = _localizer(fast, 0, n_particles=None, min_particles=50, max_particles=2000, kld_one_sequence=one)
        mcl._poses = poses
        m = max(2 * w.size, 4 * mcl.kld_bounds[0])
        sizes = []
        for seed in range(400):
            mcl.rng = np.random.default_rng(seed)
            idx = mcl._kld_indices(w)
            sizes.append(idx.size)
            if one:
                first = mcl._kld_draw(w, np.random.default_rng(seed).random(m), 50)
                assert idx[: first.size].tobytes() == first.tobytes()
        small[one] = np.mean(np.array(sizes) <= m)
    assert 0.25 < small[True] < 0.40 and small[False] > 0.45
