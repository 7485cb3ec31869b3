"""``scipy.special.logsumexp`` of a 1-D float64 array, the same bits at a fraction of the cost.

SciPy's ``logsumexp`` (1.15 and later) takes the maximum ``a_max``, counts the elements equal to
it (``m``), sums ``exp(a - a_max)`` over the *other* elements (``s``, NumPy's pairwise sum,
divided by ``m`` when non-zero) and returns ``log1p(s) + log(m) + a_max``; it also computes
``log(sum(exp(a)))`` as a fallback for non-finite results, and wraps everything in array-API
dispatch. For a filter's log-weights with a finite maximum, `logsumexp` does the same
floating-point operations (the maximum, the shift and the count in one numba pass; ``np.exp``,
``np.sum``, ``np.log1p``, ``np.log`` from NumPy as SciPy calls them) and skips the rest.

It checks once, on fixed arrays, that it reproduces the installed SciPy bit for bit, and calls
SciPy itself when that check fails or when the maximum is not finite (all ``-inf``, ``+inf`` or
NaN), so it is never less exact than SciPy. (tests/test_logsumexp.py)
"""

from __future__ import annotations

import numba
import numpy as np
from scipy.special import logsumexp as _scipy_logsumexp


@numba.njit(cache=True, nogil=True)
def _shift(a, out):  # pragma: no cover - compiled
    """``out = a - max(a)`` with the maxima set to ``-inf``; returns ``(max, count of maxima)``."""
    a_max = a[0]
    for i in range(1, a.shape[0]):
        if a[i] > a_max or np.isnan(a[i]):
            a_max = a[i]
            if np.isnan(a_max):
                break
    m = 0
    for i in range(a.shape[0]):
        if a[i] == a_max:
            out[i] = -np.inf
            m += 1
        else:
            out[i] = a[i] - a_max
    return a_max, m


def _fast(a: np.ndarray):
    shifted = np.empty_like(a)
    a_max, m = _shift(a, shifted)
    if not np.isfinite(a_max):
        return None
    m = np.float64(m)
    s = np.sum(np.exp(shifted))
    if s != 0:
        s = s / m
    return np.log1p(s) + np.log(m) + a_max


_ok: bool | None = None


def _check() -> bool:
    global _ok
    if _ok is None:
        rng = np.random.default_rng(7)
        cases = [rng.normal(0, 30, n) for n in (1, 2, 3, 17, 128, 129, 1000, 4097, 17627)]
        tie = rng.normal(-5, 1, 500)
        tie[[3, 77, 400]] = 2.5
        cases += [tie, np.array([-np.inf, 0.0, -np.inf]), np.log(rng.random(3000)) - 700.0]
        _ok = all(np.float64(_fast(c)).tobytes() == np.float64(_scipy_logsumexp(c)).tobytes() for c in cases)
    return _ok


def logsumexp(a: np.ndarray) -> np.float64:
    """``scipy.special.logsumexp(a)`` for a non-empty 1-D float64 array, bit for bit (module docstring)."""
    a = np.ascontiguousarray(a, dtype=np.float64)
    if a.ndim != 1 or a.size == 0 or not _check():
        return _scipy_logsumexp(a)
    r = _fast(a)
    return _scipy_logsumexp(a) if r is None else r
