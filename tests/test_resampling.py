import numpy as np
import pytest

from filters.smc.resampling import RESAMPLERS, effective_sample_size, get_resampler


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_counts_near_n_times_w(name):
    rng = np.random.default_rng(0)
    w = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625, 0.0])
    n, reps = w.size, 4000
    counts = np.zeros(n)
    for _ in range(reps):
        idx = RESAMPLERS[name](w, rng)
        assert idx.shape == (n,)
        assert np.all(np.diff(idx) >= 0)
        counts += np.bincount(idx, minlength=n)
    mean = counts / reps
    # unbiased: E[count_i] = N * w_i; 4000 reps make the standard error < 0.02
    np.testing.assert_allclose(mean, n * w, atol=0.06)
    assert mean[-1] == 0.0  # zero weight is never drawn


@pytest.mark.parametrize("name", ["systematic", "residual"])
def test_low_variance_schemes_give_floor_or_ceil_copies(name):
    rng = np.random.default_rng(1)
    w = rng.dirichlet(np.ones(30))
    for _ in range(200):
        c = np.bincount(RESAMPLERS[name](w, rng), minlength=30)
        # both give every particle at least floor(N w) copies; systematic at most ceil(N w)
        assert np.all(c >= np.floor(30 * w))
        if name == "systematic":
            assert np.all(c <= np.ceil(30 * w))


def test_bad_weights_and_names():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="sum to zero"):
        RESAMPLERS["systematic"](np.zeros(4), rng)
    with pytest.raises(ValueError, match="finite"):
        RESAMPLERS["multinomial"](np.array([0.5, np.nan]), rng)
    with pytest.raises(ValueError, match="non-empty"):
        RESAMPLERS["residual"](np.array([]), rng)
    with pytest.raises(ValueError, match="unknown resampler"):
        get_resampler("roulette")


def test_ess():
    assert effective_sample_size(np.ones(10)) == pytest.approx(10)
    assert effective_sample_size(np.array([1.0, 0, 0])) == pytest.approx(1)


def test_weights_whose_sum_overflows_are_scaled_not_zeroed():
    # a twenty-third tester's: [1.7e308, 1.7e308, 0] normalised to all zeros, so every resampler drew the
    # zero-weight particle and the ESS was inf
    from filters.localization.belief import summarize
    from filters.smc.pf import normalise_log_weights
    from filters.smc.resampling import RESAMPLERS, effective_sample_size, normalise_weights

    w = np.array([1.7e308, 1.7e308, 0.0])
    np.testing.assert_array_equal(normalise_weights(w), [0.5, 0.5, 0.0])
    assert effective_sample_size(w) == 2.0
    for name, resample in RESAMPLERS.items():
        assert 2 not in resample(w, np.random.default_rng(0)), name
    b = summarize(np.array([[5.0, 5, 0], [5, 5, 0], [-9, -9, 0]]), w)
    np.testing.assert_allclose(b.mean[:2], [5.0, 5.0])
    # +inf log-weights take the whole mass (the limit), where they gave uniform weights
    np.testing.assert_array_equal(normalise_log_weights(np.array([0.0, np.inf, 0.0])), [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(normalise_log_weights(np.array([np.inf, np.nan, np.inf])), [0.5, 0.0, 0.5])
