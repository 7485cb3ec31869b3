import numpy as np
import pytest

from filters.smc.firefly import (
    FAPF,
    IFAPF,
    adaptive_step,
    apply_mutation,
    ewa_resample,
    ewa_threshold,
    fa_config,
    firefly_move,
    fixed_step,
    gaussian_log_brightness,
    ifa_config,
    observation_log_brightness,
)
from filters.smc.models import GrowthModel
from filters.smc.pf import rmse


# ---- EWA step-wise resampling --------------------------------------------------------------
def _weight_cases():
    rng = np.random.default_rng(0)
    cases = [rng.dirichlet(np.full(n, a)) for n in (5, 20, 100) for a in (0.1, 1.0, 10.0)]
    cases.append(np.full(10, 0.1))  # equal weights: every particle once
    cases.append(np.r_[np.ones(9), 10.0] / 19.0)  # one heavy among equals: 9 copies + 1 mutant
    return cases


@pytest.mark.parametrize("w", _weight_cases())
def test_ewa_returns_n_indices_keeps_heaviest_and_mask_count(w):
    n = w.size
    idx, mask = ewa_resample(w)
    assert idx.shape == (n,) and mask.shape == (n,) and mask.dtype == bool
    assert idx.min() >= 0 and idx.max() < n
    assert w[idx[0]] == w.max()  # the heaviest comes first and survives
    # independent recomputation of the copy count: sum over kept of ceil(w / dbar)
    srt = np.sort(w)
    d, dhat = 0.0, []
    for i, wi in enumerate(srt, start=1):
        d = 0.8 * d + 0.2 * wi
        dhat.append(d / (1 - 0.8**i))
    dbar = np.mean(dhat)
    assert ewa_threshold(srt) == pytest.approx(dbar, rel=1e-12)
    kept = w >= dbar * (1 - 1e-9)
    copies = np.maximum(1, np.ceil(w[kept] / dbar - 1e-9)).sum()
    assert mask.sum() == max(0, n - copies)
    # every index points at a kept particle; a dropped (light) particle never reappears
    assert np.all(kept[idx])
    # unmutated copies are listed in descending weight order
    assert np.all(np.diff(w[idx[~mask]]) <= 0)


def test_ewa_specific_cases():
    idx, mask = ewa_resample(np.full(10, 0.1))
    assert sorted(idx.tolist()) == list(range(10)) and not mask.any()
    idx, mask = ewa_resample(np.r_[np.ones(9), 10.0])
    assert np.array_equal(idx, np.full(10, 9)) and mask.sum() == 1 and mask[-1]
    # finite weights whose sum overflows resample as the same weights scaled down (an audit found a cryptic error)
    for got, want in zip(ewa_resample(np.array([1e308, 1e308, 1.0])), ewa_resample(np.array([1.0, 1.0, 1e-308]))):
        np.testing.assert_array_equal(got, want)


def test_apply_mutation_perturbs_only_masked_rows_relative_to_value():
    rng = np.random.default_rng(2)
    x = np.array([[1.0, 100.0], [2.0, -50.0], [0.0, 3.0]])
    idx = np.array([1, 1, 0, 2])
    mask = np.array([False, True, True, True])
    out = apply_mutation(x, idx, mask, 0.01, rng)
    assert out.shape == (4, 2)
    assert np.array_equal(out[0], x[1])
    nz = x[idx[1:]] != 0
    assert np.all(out[1:][nz] != x[idx[1:]][nz])
    assert out[3, 0] == 0.0  # zero component stays zero: x' = x + x*mu*N(0,1)
    rel = np.abs(out[1:] - x[idx[1:]]) / np.maximum(np.abs(x[idx[1:]]), 1e-300)
    assert np.all(rel[x[idx[1:]] != 0] < 0.06)  # 6 sigma of mu = 0.01


def test_ewa_bad_input_raises():
    for bad in (np.array([]), np.array([0.5, np.nan]), np.array([-0.1, 1.1]), np.zeros(3)):
        with pytest.raises(ValueError):
            ewa_resample(bad)


# ---- brightness and step ------------------------------------------------------------------
def test_brightness_monotone_decreasing_in_both_distances():
    d = np.linspace(0.0, 10.0, 50)
    zero = np.zeros_like(d)
    for r_var, q_var in [(1.0, 1.0), (0.3, 4.0)]:
        b_obs = np.exp(gaussian_log_brightness(d, zero, r_var, q_var))
        b_state = np.exp(gaussian_log_brightness(zero + 0.5, d, r_var, q_var))
        assert np.all(np.diff(b_obs) < 0) or np.all(np.diff(b_obs[b_obs > 0]) < 0)
        assert np.all(np.diff(b_state[b_state > 0]) < 0)
        assert b_obs[0] == 1.0
    fa = observation_log_brightness(d, zero, 1.0, 1.0)
    assert np.all(np.diff(fa) < 0)
    np.testing.assert_array_equal(observation_log_brightness(d, d, 1.0, 1.0), fa)  # ignores the state term


def test_adaptive_step_shrinks_for_relatively_bright_fireflies():
    log_j = np.zeros(5)
    log_i = np.log(np.array([1e-6, 0.25, 0.5, 1.0, 2.0]))
    f = adaptive_step(log_i, log_j)
    assert np.all(np.diff(f) < 0)
    assert f[0] == pytest.approx(1.0, abs=1e-5) and f[3] == pytest.approx(np.exp(-1.0))
    assert np.all(adaptive_step(np.full(3, -1e5), np.full(3, 0.0)) > 0.999)
    np.testing.assert_array_equal(fixed_step(log_i, log_j), 1.0)
    # both brightnesses underflowed: equally bright, not NaN (an audit found NaN particles)
    np.testing.assert_array_equal(adaptive_step(np.full(2, -np.inf), np.full(2, -np.inf)), np.exp(-1.0))
    assert adaptive_step(np.array([-np.inf]), np.array([0.0]))[0] == 1.0
    assert adaptive_step(np.array([0.0]), np.array([-np.inf]))[0] == 0.0
    moved = firefly_move(
        np.arange(4.0)[:, None], np.full(4, -np.inf), 1.0, np.random.default_rng(0), step_factor=adaptive_step
    )
    assert np.all(np.isfinite(moved))


# ---- firefly move -------------------------------------------------------------------------
def test_pairwise_move_equals_sequential_firefly_loop():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(9, 2))
    log_i = rng.normal(size=9)
    log_i[2] = log_i[5]  # a tie: neither attracts the other
    moved = firefly_move(x, log_i, 0.0, np.random.default_rng(0), mode="pairwise", gamma=0.7, beta0=0.9)
    expect = x.copy()
    for i in range(9):
        xi = x[i].copy()
        for j in np.argsort(log_i, kind="stable"):
            if log_i[j] > log_i[i]:
                xi = xi + 0.9 * np.exp(-0.7 * np.sum((x[j] - x[i]) ** 2)) * (x[j] - xi)
        expect[i] = xi
    np.testing.assert_allclose(moved, expect, atol=1e-12)
    top = np.argmax(log_i)
    assert np.array_equal(moved[top], x[top])  # the brightest does not move without the random step


@pytest.mark.parametrize("mode", ["pairwise", "sampled", "brightest"])
def test_move_pulls_toward_the_brightest_and_noise_is_bounded(mode):
    rng = np.random.default_rng(5)
    x = rng.normal(size=(40, 1)) * 0.5
    log_i = -((x[:, 0] - 0.3) ** 2)
    moved = firefly_move(x, log_i, 0.0, np.random.default_rng(1), mode=mode)
    top = x[np.argmax(log_i)]
    assert np.mean(np.abs(moved - top)) < np.mean(np.abs(x - top))
    noisy = firefly_move(x, log_i, 0.4, np.random.default_rng(1), mode=mode)
    assert np.all(np.abs(noisy - moved) <= 0.2 + 1e-12)  # alpha * (rand - 0.5), alpha <= 0.4


def test_move_bad_input_raises():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError):
        firefly_move(np.empty((0, 1)), np.empty(0), 1.0, rng)
    with pytest.raises(ValueError):
        firefly_move(np.zeros((3, 1)), np.array([0.0, np.nan, 1.0]), 1.0, rng)
    with pytest.raises(ValueError):
        firefly_move(np.zeros((3, 1)), np.zeros(3), 1.0, rng, mode="swarm")


# ---- the filters --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def growth_run():
    m = GrowthModel()
    xs, ys = m.simulate(100, np.random.default_rng(0))
    return m, xs, ys


@pytest.mark.parametrize(
    "make",
    [
        lambda: FAPF(fa_config(60)),
        lambda: IFAPF(ifa_config(60)),
        lambda: IFAPF(ifa_config(60, state_reference="posterior")),
        lambda: IFAPF(ifa_config(300)),  # auto -> sampled partner above pairwise_max_n
        lambda: FAPF(fa_config(60, move_mode="brightest", n_moves=2)),
    ],
)
def test_firefly_filters_run_finite_and_deterministic(growth_run, make):
    m, xs, ys = growth_run
    a = make().run(m, ys, np.random.default_rng(7))
    b = make().run(m, ys, np.random.default_rng(7))
    c = make().run(m, ys, np.random.default_rng(8))
    assert a.shape == (100, 1) and np.all(np.isfinite(a))
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.all(np.abs(a - xs) < 60.0)  # never far off the growth model's range


# Mean RMSE over seeds 0..4 (T = 100) of each firefly filter, as a ratio to a plain PF with the same
# particle count on the same data. Measured: 1.23, 1.77, 1.81, 1.22, 0.97. The bounds are 1.3x those, so
# a 2x accuracy regression fails here (the docs report IFA-PF at about 1.8-2x the PF's error).
FIREFLY_RATIO_BOUNDS = [
    (lambda: FAPF(fa_config(60)), 60, 1.6),
    (lambda: IFAPF(ifa_config(60)), 60, 2.3),
    (lambda: IFAPF(ifa_config(60, state_reference="posterior")), 60, 2.35),
    (lambda: IFAPF(ifa_config(300)), 60, 1.6),
    (lambda: FAPF(fa_config(60, move_mode="brightest", n_moves=2)), 60, 1.26),
]


@pytest.mark.parametrize("make, n_pf, bound", FIREFLY_RATIO_BOUNDS)
def test_firefly_filters_accuracy_against_a_plain_pf(make, n_pf, bound):
    from filters.smc.pf import BootstrapPF, PFConfig

    m = GrowthModel()
    ff, pf = [], []
    for seed in range(5):
        xs, ys = m.simulate(100, np.random.default_rng(seed))
        ff.append(rmse(make().run(m, ys, np.random.default_rng(7 + seed)), xs))
        pf.append(rmse(BootstrapPF(PFConfig(n_particles=n_pf)).run(m, ys, np.random.default_rng(7 + seed)), xs))
    assert np.mean(ff) < bound * np.mean(pf)


def test_ifa_state_reference_is_the_filters_own_estimate(growth_run):
    m, _, ys = growth_run
    f = IFAPF(ifa_config(10))
    prev = np.array([2.0])
    x_pred = np.linspace(-5, 5, 10)[:, None]
    np.testing.assert_allclose(f.state_reference(m, x_pred, ys[3], 4, prev), m.transition_mean(prev[None], 4)[0])


def test_firefly_bad_input_raises(growth_run):
    m, _, ys = growth_run
    bad = ys.copy()
    bad[10, 0] = np.nan
    for f in (FAPF(fa_config(20)), IFAPF(ifa_config(20))):
        with pytest.raises(ValueError):
            f.run(m, bad, np.random.default_rng(0))
    with pytest.raises(ValueError):
        ifa_config(0)
    with pytest.raises(ValueError):
        fa_config(10, move_mode="nope")
    with pytest.raises(ValueError):
        ifa_config(10, state_reference="truth")
    for field, bad in [("alpha0", np.nan), ("gamma", np.nan), ("mutation_mu", np.nan), ("beta0", -5.0),
                       ("n_moves", 1.5), ("ewa_beta", np.nan), ("scale_alpha_by_obs_noise", 1)]:  # fmt: skip
        with pytest.raises(ValueError, match=rf"FireflyConfig\.{field} must"):
            ifa_config(10, **{field: bad})
