"""filters.smc.logsumexp.logsumexp gives scipy.special.logsumexp's bits on 1-D float64 arrays."""

import numpy as np
from scipy.special import logsumexp as scipy_lse

from filters.smc.logsumexp import _check, logsumexp


def same_bits(a, b) -> bool:
    return np.float64(a).tobytes() == np.float64(b).tobytes()


def test_self_check_passes_with_the_installed_scipy():
    assert _check()


def test_equal_to_scipy_bit_for_bit():
    rng = np.random.default_rng(1)
    for k in range(400):
        n = int(rng.integers(1, 25_000))
        a = rng.normal(rng.uniform(-800, 50), rng.uniform(0.01, 200), n)
        if k % 3 == 0:  # filter-like: -inf entries and ties at the maximum
            a[rng.random(n) < 0.2] = -np.inf
            a[rng.integers(0, n, 3)] = np.max(a[np.isfinite(a)]) if np.isfinite(a).any() else 0.0
        if k % 5 == 0:  # normalised log-weights
            a = a - scipy_lse(a)
        assert same_bits(logsumexp(a), scipy_lse(a)), k


def test_non_finite_cases_follow_scipy():
    for a in ([-np.inf, -np.inf], [np.inf, 1.0], [np.nan, 1.0], [1.0, np.nan], [0.0]):
        a = np.array(a)
        got, want = logsumexp(a), scipy_lse(a)
        assert same_bits(got, want) or (np.isnan(got) and np.isnan(want))
