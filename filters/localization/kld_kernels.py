"""Numba kernel of KLD-sampling's draw-and-count loop (`MonteCarloLocalizer._kld_draw`).

Contract: the same particle count and indices as the NumPy reference *bit for bit*, for the same
uniform draws. The reference searches every draw in the CDF (``np.searchsorted``), bins all the
drawn poses, marks each bin's first draw (``np.unique``), and evaluates Fox's bound for every
draw (a cube and a square root per draw) before taking the first draw that meets it. Here:

* the CDF search is a binary search for the same partition point (``cdf[i] <= u``; the CDF is
  non-decreasing up to its last entry, set to 1, above every draw ``u < 1``, so the predicate is
  monotone and every correct search finds the same index), started from a guide table of the CDF
  at ``K`` even steps (``K`` = the particle count), so it searches a few entries instead of all;
* bins are ``floor(x / b)`` etc., single IEEE operations as in the reference, identified in a
  dense table offset by the *particle set's* smallest bin (any one-to-one key gives the same
  first-occurrence mask);
* Fox's bound comes from a table ``bound[k]`` that NumPy filled with the reference's own formula
  for ``k = 0 .. K`` (the formula is elementwise, so the table holds the reference's values;
  ``tests/test_kld_kernels.py`` checks it bytewise);
* the loop stops at the first draw that meets the bound, so draws after it are never searched.
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def _guide(cdf):  # pragma: no cover - compiled
    """``guide[b]`` = ``np.searchsorted(cdf, b / K, side="right")`` for ``b = 0 .. K``, ``K = len(cdf)``: where
    to look for a uniform between ``b / K`` and ``(b + 1) / K`` (Chen and Asau's guide table)."""
    k = cdf.shape[0]
    guide = np.empty(k + 1, dtype=np.int64)
    i = 0
    for b in range(k + 1):
        t = b / k
        while i < k and cdf[i] <= t:
            i += 1
        guide[b] = i
    return guide


@numba.njit(cache=True, nogil=True)
def _search_right(cdf, u, guide):  # pragma: no cover - compiled
    """``np.searchsorted(cdf, u, side="right")`` clipped to ``len(cdf) - 1``, for ``0 <= u < 1``.

    The answer lies between the guide's entries one bucket either side of ``u``'s (a bucket's worth of
    slack for the rounding of ``u * K``), so the binary search runs over a few entries, not all."""
    k = cdf.shape[0]
    b = np.int64(u * k)
    lo = guide[max(b - 1, 0)]
    hi = guide[min(b + 2, k)]
    while lo < hi:
        mid = (lo + hi) >> 1
        if cdf[mid] <= u:
            lo = mid + 1
        else:
            hi = mid
    return min(lo, cdf.shape[0] - 1)


@numba.njit(cache=True, nogil=True)
def bin_extent(poses, bin_xy_m, bin_theta_rad):  # pragma: no cover - compiled
    """``(min_x, min_y, min_t, max_x, max_y, max_t)``: the smallest and largest KLD bin index along
    each axis over every pose (the reference's ``floor(x / bin)`` and ``floor((theta + pi) / bin_theta)``),
    as floats, so that spans of absurd clouds can be checked before any integer arithmetic (all NaN
    if a pose is not finite)."""
    mx = my = mt = np.inf
    ax = ay = at = -np.inf
    for i in range(poses.shape[0]):
        bx = math.floor(poses[i, 0] / bin_xy_m)
        by = math.floor(poses[i, 1] / bin_xy_m)
        bt = math.floor((poses[i, 2] + np.pi) / bin_theta_rad)
        if not (math.isfinite(bx) and math.isfinite(by) and math.isfinite(bt)):
            return np.nan, np.nan, np.nan, np.nan, np.nan, np.nan
        mx, ax = min(mx, bx), max(ax, bx)
        my, ay = min(my, by), max(ay, by)
        mt, at = min(mt, bt), max(at, bt)
    return mx, my, mt, ax, ay, at


def dense_extent(poses, bin_xy_m: float, bin_theta_rad: float, max_cells: int):
    """``(min_x, min_y, min_t, n_x, n_y, n_t)`` (ints) for `kld_draw`'s dense table of bins, or None
    when the cloud spans more than ``max_cells`` bins or its bin indices do not fit comfortably in
    int64 (the caller then runs the reference)."""
    lo_hi = bin_extent(poses, bin_xy_m, bin_theta_rad)
    if not all(math.isfinite(v) and abs(v) < 2.0**62 for v in lo_hi):
        return None
    mins = [int(v) for v in lo_hi[:3]]
    spans = [int(hi) - lo + 1 for lo, hi in zip(mins, (int(v) for v in lo_hi[3:]))]
    if spans[0] * spans[1] * spans[2] > max_cells:
        return None
    return (*mins, *spans)


@numba.njit(cache=True, nogil=True)
def kld_draw(poses, cdf, u, lo, bound, bin_xy_m, bin_theta_rad, extent, idx):  # pragma: no cover - compiled
    """Draw ancestors for the uniforms ``u`` until KLD's bound is met; returns how many were drawn.

    Args:
        poses: ``(N, 3)`` particle poses.
        cdf: ``(N,)`` cumulative normalised weights, last entry 1.
        u: ``(m,)`` uniforms in [0, 1), in draw order.
        lo: the smallest count accepted.
        bound: ``bound[k]`` = Fox's ``n_chi`` for ``k`` occupied bins, ``k = 0 .. m`` at least.
        bin_xy_m, bin_theta_rad: KLD bin sizes.
        extent: `dense_extent` of ``poses``.
        idx: ``(m,)`` int64 out: the ancestor of each draw (only the first ``n`` are written).

    Returns:
        ``n``: the first count ``j`` with ``j >= bound[k_j]`` and ``j >= lo`` (``k_j`` bins occupied
        by the first ``j`` draws), or ``m`` if none.
    """
    mx, my, mt, nx, ny, nt = extent
    seen = np.zeros(nx * ny * nt, dtype=np.bool_)
    guide = _guide(cdf)
    k = 0
    m = u.shape[0]
    for j in range(m):
        i = _search_right(cdf, u[j], guide)
        idx[j] = i
        bx = np.int64(math.floor(poses[i, 0] / bin_xy_m)) - mx
        by = np.int64(math.floor(poses[i, 1] / bin_xy_m)) - my
        bt = np.int64(math.floor((poses[i, 2] + np.pi) / bin_theta_rad)) - mt  # each in [0, n) by dense_extent
        key = (bx * ny + by) * nt + bt
        if not seen[key]:
            seen[key] = True
            k += 1
        count = j + 1
        if count >= bound[k] and count >= lo:
            return count
    return m
