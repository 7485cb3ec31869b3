"""Dot products of long float64 vectors in one fixed order, whatever NumPy's OpenBLAS thread count.

NumPy's OpenBLAS splits a dot product of more than 10,000 elements over its threads
(``kernel/x86_64/ddot.c``): thread ``k`` of ``t`` computes the dot of the ``k``-th chunk
(``ceil(remaining / threads left)`` elements) with the single-thread kernel, and the caller adds
the partial results in thread order to ``0.0``. ``a @ b`` therefore gives other bits on a machine
with another core count (or under ``OPENBLAS_NUM_THREADS``), and on a busy machine waking the
threads costs far more than the arithmetic (measured on the shared 2-core VM: ~35 us of CPU
instead of ~8 us, several ms under heavy load).

`dot` splits the same way for a *fixed* count, ``t = max(2, ceil(n / 10,000))`` chunks, computes
each chunk with ``@`` (at most 10,000 elements, so OpenBLAS keeps it on one thread) and adds the
partial results in order to ``0.0``; vectors of at most 10,000 elements are one ``@``. So the
result does not depend on the thread count, and for ``n <= 20,000`` it is the bits of ``a @ b``
under OpenBLAS with 2 threads (the machines the project's figures were made on), which is what
``a @ b`` gave there before. What still differs between machines is OpenBLAS's single-thread
kernel itself, chosen per CPU architecture. (tests/test_blas_dot.py)
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


def openblas_threads() -> int | None:
    """NumPy's OpenBLAS thread count now, or None if NumPy's BLAS is not a known OpenBLAS."""
    return None if _get_threads is None else int(_get_threads())


def _chunked(a: np.ndarray, b: np.ndarray, t: int) -> float | None:
    """OpenBLAS's split over ``t`` threads, each chunk with ``@``; None if a chunk would be longer
    than 10,000 elements (OpenBLAS would split it again)."""
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


def chunks_for(n: int) -> int:
    """The fixed chunk count of `dot` for ``n`` elements."""
    return 1 if n <= _SPLIT_ABOVE else max(2, -(-n // _SPLIT_ABOVE))


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """The dot product of two contiguous float64 vectors of equal length in the fixed order of the
    module docstring (independent of the OpenBLAS thread count)."""
    return _chunked(a, b, chunks_for(a.shape[0]))
