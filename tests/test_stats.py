"""filters.experiments.stats against the closed-form formulas and the hand-written code it replaced."""

import math

import numpy as np
import pytest

from filters.experiments.stats import (
    normal_mean_interval,
    paired_bootstrap_interval,
    relative_reduction_pct,
    t_mean_interval,
    wilson_interval,
)


def _wilson_closed_form(k, n, z=1.959963984540054):
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return centre - half, centre + half


@pytest.mark.parametrize("k,n", [(0, 10), (3, 10), (8, 20), (20, 20), (57, 200), (1, 1)])
def test_wilson_matches_the_closed_form(k, n):
    assert wilson_interval(k, n) == pytest.approx(_wilson_closed_form(k, n), abs=1e-12)


def test_wilson_empty_and_bad_counts():
    assert all(math.isnan(v) for v in wilson_interval(0, 0))
    for k, n in [(-1, 5), (6, 5), (0, -1)]:
        with pytest.raises(ValueError, match="k <= n"):
            wilson_interval(k, n)
    with pytest.raises(ValueError, match="level"):
        wilson_interval(1, 2, level=1.0)


def test_t_interval_matches_the_closed_form():
    x = np.array([3.1, 2.7, 4.0, 3.3, 2.9])
    m, h = t_mean_interval(x)
    # t_{0.975, 4} = 2.7764451051977987
    assert m == pytest.approx(x.mean()) and h == pytest.approx(2.7764451051977987 * x.std(ddof=1) / math.sqrt(5))
    m90, h90 = t_mean_interval(x, level=0.9)  # t_{0.95, 4} = 2.131846786326649
    assert h90 == pytest.approx(2.131846786326649 * x.std(ddof=1) / math.sqrt(5))
    assert math.isnan(t_mean_interval([2.0])[1]) and t_mean_interval([2.0])[0] == 2.0
    assert all(math.isnan(v) for v in t_mean_interval([]))
    with pytest.raises(ValueError, match="one-dimensional"):
        t_mean_interval(np.ones((2, 2)))


def test_normal_interval_matches_the_former_1_96_formula():
    x = np.random.default_rng(0).normal(size=30)
    m, h = normal_mean_interval(x)
    assert m == pytest.approx(x.mean())
    assert h == pytest.approx(1.96 * x.std(ddof=1) / math.sqrt(x.size), rel=3e-5)  # z = 1.959964 vs 1.96
    assert math.isnan(normal_mean_interval([1.0])[1])


def _former_improvement_ci(base, new, rng, n_boot=4000):
    """The paired bootstrap formerly written by hand in scripts/repro_paper001.py."""
    point = 100.0 * (1.0 - new.mean() / base.mean())
    idx = rng.integers(0, base.size, size=(n_boot, base.size))
    boot = 100.0 * (1.0 - new[idx].mean(axis=1) / base[idx].mean(axis=1))
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(point), float(lo), float(hi)


def test_paired_bootstrap_gives_the_former_numbers_for_the_same_seed():
    g = np.random.default_rng(1)
    base = g.gamma(2.0, size=40) + 1.0
    new = base * g.uniform(0.5, 1.2, size=40)
    r1, r2 = np.random.default_rng(5), np.random.default_rng(5)
    got = paired_bootstrap_interval(base, new, r1)
    want = _former_improvement_ci(base, new, r2)
    assert got == pytest.approx(want, rel=1e-12)
    assert r1.random() == r2.random()  # same number of draws: later results in a script do not shift
    assert got[0] == pytest.approx(float(relative_reduction_pct(base, new)))
    assert got[1] < got[0] < got[2]


def test_paired_bootstrap_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="paired"):
        paired_bootstrap_interval(np.ones(3), np.ones(4), rng)
    with pytest.raises(ValueError, match="n_resamples"):
        paired_bootstrap_interval(np.ones(3), np.ones(3), rng, n_resamples=0)


def test_holm_adjusted_by_hand():
    from filters.experiments.stats import holm_adjusted

    # sorted 0.01, 0.02, 0.04, 0.3 with m = 4: 0.04, 0.06, 0.08 -> running max, 0.3 (order restored)
    np.testing.assert_allclose(holm_adjusted([0.04, 0.01, 0.3, 0.02]), [0.08, 0.04, 0.3, 0.06])
    np.testing.assert_allclose(holm_adjusted([0.5, 0.5]), [1.0, 1.0])  # capped at 1
    out = holm_adjusted([np.nan, 0.02, 0.03])  # NaN: not counted, stays NaN
    assert np.isnan(out[0])
    np.testing.assert_allclose(out[1:], [0.04, 0.04])
    assert holm_adjusted([]).size == 0
    with pytest.raises(ValueError, match="p-values"):
        holm_adjusted([1.5])


def test_mcnemar_exact_p_is_the_two_sided_binomial_tail_of_the_discordant_pairs():
    from filters.experiments.stats import mcnemar_exact_p

    # at 1/2 the two-sided p is twice the smaller tail: 2 * P(X <= min(a, b)), X ~ Bin(a + b, 1/2), at most 1
    for a, b in [(0, 5), (1, 9), (9, 1), (3, 3), (2, 1), (19, 62)]:
        n = a + b
        tail = sum(math.comb(n, i) for i in range(min(a, b) + 1)) / 2**n
        assert mcnemar_exact_p(a, b) == pytest.approx(min(1.0, 2 * tail), rel=1e-12)
    assert mcnemar_exact_p(0, 5) == pytest.approx(0.0625)
    assert mcnemar_exact_p(0, 0) == 1.0  # no discordant pair: no evidence either way
    with pytest.raises(ValueError, match="counts must be >= 0"):
        mcnemar_exact_p(-1, 3)


def test_cluster_bootstrap_resamples_whole_clusters():
    from filters.experiments.stats import cluster_bootstrap_interval, wilson_interval

    rng = np.random.default_rng(3)
    # 20 clusters of 10 values each, all-or-nothing per cluster: the effective sample is 20, not 200
    per = (rng.random(20) < 0.5).astype(float)
    x, clusters = np.repeat(per, 10), np.repeat(np.arange(20), 10)
    point, lo, hi = cluster_bootstrap_interval(x, clusters, np.random.default_rng(0))
    w_lo, w_hi = wilson_interval(int(x.sum()), x.size)
    assert point == pytest.approx(x.mean()) and lo <= point <= hi
    assert hi - lo > 1.8 * (w_hi - w_lo)
    # labels may be any hashables; the same seed gives the same interval
    names = [("lab", int(c)) for c in clusters]
    assert cluster_bootstrap_interval(x, names, np.random.default_rng(0)) == (point, lo, hi)
    # unequal cluster sizes: the mean is over values, not over cluster means
    y, c2 = np.array([1.0, 1.0, 1.0, 0.0]), np.array([0, 0, 0, 1])
    assert cluster_bootstrap_interval(y, c2, np.random.default_rng(0))[0] == 0.75


@pytest.mark.parametrize(
    "values, clusters, kwargs, match",
    [
        ([1.0, 0.0], [0], {}, "same length"),
        ([1.0, 0.0], [0, 0], {}, "at least two clusters"),
        ([1.0, 0.0], [0, 1], {"n_resamples": 0}, "n_resamples"),
        ([1.0, 0.0], [0, 1], {"level": 1.0}, "level"),
        ([[1.0], [0.0]], [0, 1], {}, "one-dimensional"),
    ],
)
def test_cluster_bootstrap_refuses_bad_input(values, clusters, kwargs, match):
    from filters.experiments.stats import cluster_bootstrap_interval

    with pytest.raises(ValueError, match=match):
        cluster_bootstrap_interval(values, clusters, np.random.default_rng(0), **kwargs)


def test_paper000_claim_verdicts_tell_a_contradiction_from_no_evidence():
    """An outside audit: "does not reproduce" was printed whenever a test was not significant, even for a two-run
    smoke run where no test could be."""
    from filters.experiments.paper000 import MIN_VERDICT_RUNS, claim_verdict

    n = MIN_VERDICT_RUNS
    assert claim_verdict([-1, -1], n, "FastSLAM") == "reproduces in our setup"
    assert claim_verdict([-1, 1], n, "EKF-SLAM").startswith(
        "does not reproduce in our setup: WOCPF's pose error is significantly"
    )
    assert claim_verdict([0, 0], n, "FastSLAM") == (
        "inconclusive in our setup: no setting with a significant difference over 10 runs (not shown, not ruled out)"
    )
    assert claim_verdict([0, -1], n, "FastSLAM") == (  # a review's: said "no setting with a significant difference"
        "inconclusive in our setup: significantly lower in 1 of 2 settings, not in every one (over 10 runs)"
    )
    assert claim_verdict([0, 0], n - 1, "FastSLAM").startswith("no verdict")


def test_clustered_wilson_widens_by_the_design_effect_and_keeps_wilson_at_the_edges():
    from filters.experiments.stats import clustered_wilson_interval, wilson_interval

    per = np.array([1.0, 0.0] * 10)  # 20 all-or-nothing clusters of 10
    effect, lo, hi = clustered_wilson_interval(np.repeat(per, 10), np.repeat(np.arange(20), 10))
    assert effect == pytest.approx(10 * 20 / 19)  # each cluster counts as about one outcome
    w_lo, w_hi = wilson_interval(100, 200)
    assert lo < w_lo and hi > w_hi and lo == pytest.approx(1 - hi)
    # independent outcomes (each its own cluster): about Wilson's
    x = (np.random.default_rng(0).random(300) < 0.4).astype(float)
    effect, lo, hi = clustered_wilson_interval(x, np.arange(300))
    assert effect == pytest.approx(1.0, abs=0.01) and (lo, hi) == pytest.approx(
        wilson_interval(int(x.sum()), 300), abs=1e-3
    )
    # every outcome alike: nothing measures the clusters' agreement, so the worst case, each cluster one outcome
    assert clustered_wilson_interval(np.ones(50), np.arange(50) // 5) == pytest.approx((5.0, *wilson_interval(10, 10)))
    assert clustered_wilson_interval(np.zeros(4), np.arange(4)) == pytest.approx((1.0, *wilson_interval(0, 4)))
    with pytest.raises(ValueError, match="0 or 1"):
        clustered_wilson_interval([0.5, 1.0], [0, 1])
    with pytest.raises(ValueError, match="at least two clusters"):
        clustered_wilson_interval([0.0, 1.0], [0, 0])
