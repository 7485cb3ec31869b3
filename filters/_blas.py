"""``a @ b`` for long float64 vectors with the same bits, without waking OpenBLAS's threads.

NumPy's OpenBLAS splits a dot product of more than 10,000 elements over its threads
(``kernel/x86_64/ddot.c``): thread ``k`` of ``t`` computes the dot of the ``k``-th chunk
(``ceil(remaining / threads left)`` elements) with the single-thread kernel, and the caller adds
the partial results in thread order to ``0.0``. The result therefore depends on the thread
count, and on a busy machine waking the threads costs far more than the arithmetic (measured
on the shared 2-core VM: ~35 us of CPU instead of ~8 us, several ms under heavy load).

`dot` computes the same chunks itself, each one single-threaded (a chunk has at most
10,000 elements, so OpenBLAS does not split it again), and adds them in the same order: the
same bits as ``a @ b`` with the process's current OpenBLAS thread count. It checks that claim
once per thread count on fixed vectors and falls back to ``a @ b`` when the check fails, when
the OpenBLAS thread count cannot be read (another BLAS), or when a chunk would be longer than
10,000 elements; so it is never *less* exact than ``a @ b``, only sometimes not faster.
(tests/test_blas_dot.py)
"""

from __future__ import annotations

import ctypes
import glob
import os

import numpy as np

_SPLIT_ABOVE = 10_000
"""OpenBLAS computes dot products of at most this many elements on one thread."""

_GETTERS = ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads64_", "openblas_get_num_threads")


def _find_openblas():
    """``(library, get_num_threads)`` of NumPy's bundled OpenBLAS, or ``(None, None)``."""
    base = os.path.dirname(os.path.dirname(np.__file__))
    paths = []
    for pattern in ("numpy.libs/*openblas*", "numpy/.libs/*openblas*", "numpy/.dylibs/*openblas*"):
        paths += glob.glob(os.path.join(base, pattern))
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in _GETTERS:
            f = getattr(lib, name, None)
            if f is not None:
                f.restype = ctypes.c_int
                f.argtypes = []
                return lib, f
    return None, None


_lib, _get_threads = _find_openblas()
_verified: dict[int, bool] = {}


def openblas_threads() -> int | None:
    """NumPy's OpenBLAS thread count now, or None if NumPy's BLAS is not a known OpenBLAS."""
    return None if _get_threads is None else int(_get_threads())


def _chunked(a: np.ndarray, b: np.ndarray, t: int) -> float | None:
    n = a.shape[0]
    if t <= 1 or n <= _SPLIT_ABOVE:
        return a @ b
    acc, i0, rem = 0.0, 0, n
    for left in range(t, 0, -1):
        width = (rem + left - 1) // left
        if width > _SPLIT_ABOVE:
            return None
        acc = acc + (a[i0 : i0 + width] @ b[i0 : i0 + width])
        i0 += width
        rem -= width
    return acc


def _check(t: int) -> bool:
    if t not in _verified:
        rng = np.random.default_rng(12345)
        ok = True
        for n in (10_001, 10_002, 13_337, 15_000, 19_999, 20_000):
            a, b = rng.random(n), rng.normal(0.0, 3.0, n)
            r = _chunked(a, b, t)
            ok &= r is None or bool(np.float64(r).tobytes() == np.float64(a @ b).tobytes())
        _verified[t] = ok
    return _verified[t]


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """``a @ b`` of two contiguous float64 vectors of equal length, bit for bit (module docstring)."""
    if a.shape[0] <= _SPLIT_ABOVE:
        return a @ b
    t = openblas_threads()
    if t is None or not _check(t):
        return a @ b
    r = _chunked(a, b, t)
    return a @ b if r is None else r
