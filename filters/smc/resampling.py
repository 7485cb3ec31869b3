"""Resampling schemes as plain functions ``indices = scheme(weights, rng)``.

Each takes normalised weights ``(N,)`` (non-negative, summing to 1) and a
``np.random.Generator`` and returns ``N`` int64 ancestor indices, sorted
ascending. Schemes are looked up by name in `RESAMPLERS`.
(Douc, Cappé & Moulines 2005 compare them; systematic has the lowest variance
in practice and is the default everywhere here.)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


def normalise_weights(weights: np.ndarray) -> np.ndarray:
    """Weights ``(N,)`` divided by their sum; ValueError if empty, not 1D, negative, non-finite or all zero."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1D array, got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and non-negative")
    with np.errstate(over="ignore"):
        total = w.sum()
    if not total > 0:
        raise ValueError("weights sum to zero: nothing to resample from")
    if not np.isfinite(total):  # finite weights whose sum overflows: scale them first (w / inf would be all 0)
        w = w / w.max()
        total = w.sum()
    return w / total


def closed_cdf(w: np.ndarray) -> np.ndarray:
    """``np.cumsum(w)`` of normalised weights with the last entry set to exactly 1 (above every pointer
    in [0, 1), whatever the rounding of the sum)."""
    cdf = np.cumsum(w)
    cdf[-1] = 1.0
    return cdf


def inverse_cdf(w: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices ``i`` with ``cdf[i-1] <= u < cdf[i]`` for normalised weights ``w`` and pointers ``u`` in [0, 1)."""
    return np.minimum(np.searchsorted(closed_cdf(w), u, side="right"), w.size - 1).astype(np.int64)


def multinomial(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Independent draws from the categorical distribution (the "roulette wheel")."""
    w = normalise_weights(weights)
    return inverse_cdf(w, np.sort(rng.random(w.size)))


def stratified(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform draw in each of N equal strata of [0, 1)."""
    w = normalise_weights(weights)
    n = w.size
    return inverse_cdf(w, (np.arange(n) + rng.random(n)) / n)


def systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One uniform offset shared by N evenly spaced pointers."""
    w = normalise_weights(weights)
    n = w.size
    return inverse_cdf(w, (np.arange(n) + rng.random()) / n)


def residual(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Deterministic floor(N*w) copies, the remainder by multinomial draws on the residuals."""
    w = normalise_weights(weights)
    n = w.size
    counts = np.floor(n * w).astype(np.int64)
    rest = n - counts.sum()
    idx = np.repeat(np.arange(n), counts)
    if rest > 0:
        res = n * w - counts
        extra = inverse_cdf(res / res.sum(), np.sort(rng.random(rest)))
        idx = np.sort(np.concatenate([idx, extra]))
    return idx


RESAMPLERS: dict[str, Callable[[np.ndarray, np.random.Generator], np.ndarray]] = {
    "multinomial": multinomial,
    "stratified": stratified,
    "systematic": systematic,
    "residual": residual,
}


def get_resampler(name: str) -> Callable[[np.ndarray, np.random.Generator], np.ndarray]:
    """The resampling function called ``name``; a clear error lists the known ones."""
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(f"unknown resampler {name!r}; choose one of {sorted(RESAMPLERS)}") from None


def effective_sample_size(weights: np.ndarray) -> float:
    """Kish's ESS ``1 / sum(w^2)`` of normalised weights (between 1 and N)."""
    w = normalise_weights(weights)
    return float(1.0 / np.sum(w * w))
