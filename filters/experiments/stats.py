"""Confidence intervals used by the evaluation and reproduction scripts, all from `scipy.stats`.

* `wilson_interval` -- Wilson interval of a binomial rate ``k / n``.
* `t_mean_interval` -- mean and Student-t half-width of a sample mean.
* `normal_mean_interval` -- mean and normal-approximation half-width (``z * s / sqrt(n)``).
* `paired_bootstrap_interval` -- percentile bootstrap interval of a statistic of paired samples.
* `cluster_bootstrap_interval` -- percentile bootstrap interval of a mean whose values come in clusters (the
  episodes of one layout), the clusters resampled whole.
* `clustered_wilson_interval` -- Wilson interval of a rate whose outcomes come in clusters, at the effective
  sample size the clusters leave (Kish's design effect).
* `holm_adjusted` -- Holm's step-down adjustment of p-values for a family of tests.
* `mcnemar_exact_p` -- McNemar's exact test of paired successes, from the discordant pairs.

Effective sample size lives with the weights it describes:
`filters.smc.resampling.effective_sample_size`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy import stats

__all__ = [
    "wilson_interval",
    "t_mean_interval",
    "normal_mean_interval",
    "paired_bootstrap_interval",
    "cluster_bootstrap_interval",
    "clustered_wilson_interval",
    "relative_reduction_pct",
    "holm_adjusted",
    "mcnemar_exact_p",
]


def _check_level(level: float) -> None:
    if not 0.0 < level < 1.0:
        raise ValueError(f"level must be in (0, 1), got {level}")


def wilson_interval(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Wilson ``level`` interval ``(low, high)`` of the rate ``k / n`` (fractions in [0, 1]).

    ``n == 0`` gives ``(nan, nan)``. Raises ``ValueError`` unless ``0 <= k <= n``.
    """
    _check_level(level)
    if n < 0 or k < 0 or k > n:
        raise ValueError(f"need 0 <= k <= n, got k={k}, n={n}")
    if n == 0:
        return (math.nan, math.nan)
    ci = stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=level, method="wilson")
    return (float(ci.low), float(ci.high))


def _sample(x) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise ValueError(f"x must be one-dimensional, got shape {x.shape}")
    return x


def _mean_interval(x, level: float, quantile: Callable[[float, int], float]) -> tuple[float, float]:
    """``(mean, quantile(q, n) * s / sqrt(n))`` with ``q = (1 + level) / 2``; see the two callers."""
    _check_level(level)
    x = _sample(x)
    if x.size == 0:
        return (math.nan, math.nan)
    if x.size < 2:
        return (float(x.mean()), math.nan)
    half = quantile(0.5 + level / 2, x.size) * x.std(ddof=1) / math.sqrt(x.size)
    return (float(x.mean()), float(half))


def t_mean_interval(x, level: float = 0.95) -> tuple[float, float]:
    """``(mean, half_width)`` of the Student-t ``level`` interval of the mean of ``x``.

    The half-width is ``t_{(1+level)/2, n-1} * s / sqrt(n)`` with the sample standard deviation ``s``
    (``ddof=1``); it is ``nan`` for fewer than two values (and the mean too for none).
    """
    return _mean_interval(x, level, lambda q, n: stats.t.ppf(q, n - 1))


def normal_mean_interval(x, level: float = 0.95) -> tuple[float, float]:
    """``(mean, half_width)`` of the normal-approximation ``level`` interval of the mean of ``x``.

    The half-width is ``z_{(1+level)/2} * s / sqrt(n)`` (``z = 1.959964`` at 95 %), ``s`` with
    ``ddof=1``; ``nan`` for fewer than two values (and the mean too for none).
    """
    return _mean_interval(x, level, lambda q, n: stats.norm.ppf(q))


def relative_reduction_pct(base: np.ndarray, new: np.ndarray, axis: int = -1) -> np.ndarray:
    """``100 * (1 - mean(new) / mean(base))`` along ``axis`` (percent; positive = ``new`` is smaller)."""
    return 100.0 * (1.0 - np.mean(new, axis=axis) / np.mean(base, axis=axis))


def paired_bootstrap_interval(
    base,
    new,
    rng: np.random.Generator,
    statistic: Callable[..., np.ndarray] = relative_reduction_pct,
    n_resamples: int = 4000,
    level: float = 0.95,
) -> tuple[float, float, float]:
    """``(point, low, high)``: ``statistic(base, new)`` and its paired percentile bootstrap interval.

    Pairs ``(base[i], new[i])`` are resampled together (``scipy.stats.bootstrap(paired=True)``), so
    run-to-run variation shared by both methods cancels. ``statistic`` must be vectorised over an
    ``axis`` keyword. The draws come from ``rng`` (``n_resamples`` rows of ``rng.integers``).
    """
    _check_level(level)
    base, new = _sample(base), _sample(new)
    if base.shape != new.shape or base.size < 2:
        raise ValueError(f"base and new must be paired samples of >= 2 values, got {base.shape} and {new.shape}")
    if n_resamples < 1:
        raise ValueError(f"n_resamples must be >= 1, got {n_resamples}")
    res = stats.bootstrap(
        (base, new),
        statistic,
        paired=True,
        vectorized=True,
        n_resamples=n_resamples,
        confidence_level=level,
        method="percentile",
        rng=rng,
    )
    ci = res.confidence_interval
    return (float(statistic(base, new)), float(ci.low), float(ci.high))


def _ratio_of_sums(sums: np.ndarray, counts: np.ndarray, axis: int = -1) -> np.ndarray:
    return np.sum(sums, axis=axis) / np.sum(counts, axis=axis)


def cluster_bootstrap_interval(
    values, clusters, rng: np.random.Generator, n_resamples: int = 4000, level: float = 0.95
) -> tuple[float, float, float]:
    """``(point, low, high)``: the mean of ``values`` and its percentile bootstrap interval with whole clusters
    resampled.

    ``clusters[i]`` names the cluster of ``values[i]`` (any hashable labels, e.g. the layout an episode ran on).
    Where outcomes cluster (the starts of one layout succeed or fail together), resampling single values treats
    them as independent and gives too narrow an interval; this resamples the clusters, each with all its values,
    and takes the mean over the values drawn (a ratio of the drawn clusters' sums to their sizes;
    ``scipy.stats.bootstrap`` over the clusters' ``(sum, size)`` pairs). For a paired comparison pass the
    per-case differences. The draws come from ``rng``.

    Raises:
        ValueError: ``values`` and ``clusters`` of different lengths, fewer than two clusters (no spread to
            resample), ``n_resamples < 1``, or a ``level`` outside (0, 1).
    """
    _check_level(level)
    x, sums, counts = _cluster_sums(values, clusters)
    _, low, high = paired_bootstrap_interval(sums, counts, rng, _ratio_of_sums, n_resamples, level)
    return (float(x.mean()), low, high)


def _cluster_sums(values, clusters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(values, per-cluster sums, per-cluster sizes)``; ValueError unless there are values from two clusters."""
    x = _sample(values)
    labels = list(clusters)
    if len(labels) != x.size:
        raise ValueError(f"values and clusters must have the same length, got {x.size} and {len(labels)}")
    index: dict = {}
    ids = np.array([index.setdefault(c, len(index)) for c in labels], dtype=np.int64)
    if len(index) < 2:
        raise ValueError(f"need values from at least two clusters to resample, got {len(index)}")
    sums = np.bincount(ids, weights=x, minlength=len(index))
    return x, sums, np.bincount(ids, minlength=len(index)).astype(np.float64)


def clustered_wilson_interval(outcomes, clusters, level: float = 0.95) -> tuple[float, float, float]:
    """``(design_effect, low, high)``: the Wilson ``level`` interval of the rate of 0/1 ``outcomes`` whose
    ``clusters[i]`` (e.g. the layout of an episode) share their outcomes, at the effective sample size
    ``n / design_effect``.

    The design effect is the variance of the rate as a ratio of cluster sums (the linearised between-cluster
    variance, ``C / (C - 1) * sum_c (y_c - p m_c)^2 / n^2``) over the binomial ``p (1 - p) / n``, at least 1. When
    every outcome is the same there is no spread to measure how much a cluster's outcomes agree, and it takes the
    worst case, ``n / C``: each cluster counts as one outcome. Unlike a percentile bootstrap it keeps Wilson's
    behaviour near 0 and 1, where a bootstrap interval collapses onto the observed rate.

    Raises:
        ValueError: outcomes other than 0 and 1, lengths that differ, fewer than two clusters, or a bad ``level``.
    """
    _check_level(level)
    x, sums, sizes = _cluster_sums(outcomes, clusters)
    if np.any((x != 0.0) & (x != 1.0)):
        raise ValueError("outcomes must be 0 or 1")
    n, p, c = x.size, float(x.mean()), sums.size
    binomial = p * (1.0 - p) / n
    between = c / (c - 1) * float(np.sum((sums - p * sizes) ** 2)) / n**2
    effect = max(1.0, between / binomial) if binomial > 0 else n / c
    m = n / effect
    z = float(stats.norm.ppf(0.5 + level / 2))
    centre = (p + z * z / (2 * m)) / (1 + z * z / m)
    half = z / (1 + z * z / m) * math.sqrt(p * (1 - p) / m + z * z / (4 * m * m))
    return (effect, max(0.0, centre - half), min(1.0, centre + half))


def mcnemar_exact_p(only_a: int, only_b: int) -> float:
    """McNemar's exact two-sided p-value for paired binary outcomes: ``only_a`` pairs where only A succeeded,
    ``only_b`` where only B did (the concordant pairs do not enter); a binomial test of ``only_a`` of
    ``only_a + only_b`` at 1/2. 1.0 without discordant pairs. Raises ``ValueError`` on a negative count."""
    if only_a < 0 or only_b < 0:
        raise ValueError(f"counts must be >= 0, got {only_a} and {only_b}")
    n = int(only_a) + int(only_b)
    return float(stats.binomtest(int(only_a), n).pvalue) if n else 1.0


def holm_adjusted(p_values) -> np.ndarray:
    """Holm's step-down adjusted p-values of a family of tests (same order as given).

    Rejecting every test whose adjusted p-value is below ``alpha`` keeps the family-wise error
    rate at ``alpha``: with m tests, one of them "significant" at 0.05 by chance alone is likely
    when m is large, and this correction accounts for it. NaN p-values stay NaN and are not counted.
    """
    p = np.asarray(p_values, dtype=np.float64).reshape(-1)
    out = np.full(p.shape, np.nan)
    ok = np.flatnonzero(np.isfinite(p))
    if ok.size == 0:
        return out
    if np.any((p[ok] < 0) | (p[ok] > 1)):
        raise ValueError(f"p-values must lie in [0, 1], got {p[ok].tolist()}")
    order = ok[np.argsort(p[ok], kind="stable")]
    m = order.size
    adjusted = np.minimum(1.0, np.maximum.accumulate((m - np.arange(m)) * p[order]))
    out[order] = adjusted
    return out
