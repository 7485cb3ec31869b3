"""filters._blas.dot gives the bits of ``a @ b`` (NumPy's OpenBLAS, whatever its thread count)."""

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


def test_dot_equals_matmul_bit_for_bit():
    rng = np.random.default_rng(0)
    sizes = [1, 7, 9999, 10_000, 10_001, 10_002, 12_345, 17_627, 19_999, 20_000, 20_001, 25_000, 40_000]
    sizes += [int(n) for n in rng.integers(10_001, 20_001, 40)]
    before = _blas.openblas_threads()
    thread_counts = [None] if before is None else sorted({1, 2, before})
    try:
        for t in thread_counts:
            if t is not None:
                assert set_threads(t)
            for n in sizes:
                w = rng.random(n)
                w /= w.sum()
                for x in (rng.normal(0.0, 5.0, n), rng.uniform(-1, 1, n), np.exp(-rng.random(n) * 40)):
                    assert same_bits(_blas.dot(w, x), w @ x), (t, n)
    finally:
        if before is not None:
            set_threads(before)


def test_chunks_never_exceed_the_single_thread_size():
    a = np.ones(25_000)
    assert _blas._chunked(a, a, 2) is None  # 12,500-element chunks: OpenBLAS would split them again
    assert _blas._chunked(a, a, 3) == 25_000.0


@pytest.mark.skipif(_blas.openblas_threads() is None, reason="NumPy's BLAS is not OpenBLAS")
def test_thread_count_is_read():
    assert _blas.openblas_threads() >= 1
