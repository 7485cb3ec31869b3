"""filters._blas.dot: one order whatever NumPy's OpenBLAS thread count; ``a @ b``'s bits under 2 threads."""

import ctypes

import numpy as np
import pytest

from filters import _blas


def set_threads(t: int) -> bool:
    """Set NumPy's OpenBLAS thread count (False if NumPy's BLAS is not a known OpenBLAS)."""
    if _blas._lib is None:
        return False
    for name in ("scipy_openblas_set_num_threads64_", "openblas_set_num_threads64_", "openblas_set_num_threads"):
        f = getattr(_blas._lib, name, None)
        if f is not None:
            f.argtypes = [ctypes.c_int]
            f(t)
            return True
    return False


def same_bits(a, b) -> bool:
    return np.float64(a).tobytes() == np.float64(b).tobytes()


@pytest.mark.skipif(_blas.openblas_threads() is None, reason="NumPy's BLAS is not OpenBLAS: no thread count to vary")
def test_dot_does_not_depend_on_the_thread_count_and_is_matmul_under_two_threads():
    rng = np.random.default_rng(0)
    sizes = [1, 7, 9999, 10_000, 10_001, 10_002, 12_345, 17_627, 19_999, 20_000, 20_001, 25_000, 40_000]
    sizes += [int(n) for n in rng.integers(10_001, 20_001, 30)]
    vectors = []
    for n in sizes:
        w = rng.random(n)
        w /= w.sum()
        vectors += [(w, x) for x in (rng.normal(0.0, 5.0, n), rng.uniform(-1, 1, n), np.exp(-rng.random(n) * 40))]
    before = _blas.openblas_threads()
    results = {}
    try:
        for t in [None] if before is None else [1, 2, before]:
            if t is not None:
                assert set_threads(t)
            results[t] = [np.float64(_blas.dot(w, x)).tobytes() for w, x in vectors]
            if t == 2:  # the bits of the machines the figures were made on
                for w, x in vectors:
                    if w.size <= 20_000:
                        assert same_bits(_blas.dot(w, x), w @ x), w.size
    finally:
        if before is not None:
            set_threads(before)
    first = next(iter(results.values()))
    assert all(r == first for r in results.values())
    if before is not None:  # and the thread count does change a @ b itself, which is the point
        assert set_threads(1)
        try:
            one = [np.float64(w @ x).tobytes() for w, x in vectors]
        finally:
            set_threads(before)
        assert one != first or before == 1


def test_chunks_never_exceed_the_single_thread_size():
    a = np.ones(25_000)
    assert _blas._chunked(a, a, 2) is None  # 12,500-element chunks: OpenBLAS would split them again
    assert _blas._chunked(a, a, 3) == 25_000.0
    assert [_blas.chunks_for(n) for n in (1, 10_000, 10_001, 20_000, 20_001, 40_000)] == [1, 1, 2, 2, 3, 4]


@pytest.mark.skipif(_blas.openblas_threads() is None, reason="NumPy's BLAS is not OpenBLAS")
def test_thread_count_is_read():
    assert _blas.openblas_threads() >= 1
