"""Numba kernels of the belief summary (`filters.localization.belief`), one pass per stage.

Contract: every kernel reproduces the NumPy reference in `filters.localization.belief`
*bit for bit*, not just closely. That is possible because the reference's float results come
from operations whose order is fixed and reproducible here without fastmath:

* ``np.floor(v / size)``, ``wrap_angle`` (``(a + pi) % 2pi - pi``, NumPy's floored modulo,
  which numba's float ``%`` implements with the same ``fmod`` steps), products and quotients
  are single IEEE operations;
* ``np.bincount(keys, weights=v)`` adds ``v[i]`` into its bin in index order, as the loops
  below do.

What is *not* reproducible here stays in NumPy in the callers: BLAS dot products (OpenBLAS
splits long ones over threads), pairwise ``np.sum`` and the transcendental functions ``np.log`` and
``np.arctan2``, whose SIMD versions may differ from libm in the last bit. The headings' ``cos`` and
``sin`` are the exception: NumPy's float64 ones are the C library's, which `filters.pose.cos_sin` calls
too (a test checks it on each machine the suite runs on). Tests: ``tests/test_belief_kernels.py``
(kernels against the reference on random and adversarial clouds) and ``tests/test_fast_path.py``
(whole seeded episodes).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from llvmlite import ir
from numba.core import types
from numba.extending import intrinsic

_TWO_PI = 2.0 * np.pi


@numba.njit(cache=True, nogil=True, inline="always")
def _wrap(a):  # pragma: no cover - compiled
    """``filters.pose.wrap_angle`` for one float, bit for bit.

    ``y % 2pi`` (floored modulo) is ``y`` itself when ``0 <= y < 2pi`` (``fmod`` is exact and
    needs no sign fix; a zero becomes ``+0.0`` as in NumPy), so the slow ``fmod`` only runs for
    headings outside ``[-pi, pi)``; the particles' headings are almost always inside.
    """
    y = a + np.pi
    if 0.0 < y < _TWO_PI:
        return y - np.pi
    if y == 0.0:
        return 0.0 - np.pi
    return y % _TWO_PI - np.pi


@numba.njit(cache=True, nogil=True)
def residuals(poses, mx, my, mth, out):  # pragma: no cover - compiled
    """``out (3, N)`` = ``(x - mx, y - my, wrap(theta - mth))``, the reference's ``np.stack``."""
    for i in range(poses.shape[0]):
        out[0, i] = poses[i, 0] - mx
        out[1, i] = poses[i, 1] - my
        out[2, i] = _wrap(poses[i, 2] - mth)


@numba.njit(cache=True, nogil=True)
def raster_bins(poses, bin_xy_m, nt, scale, ix, iy, it):  # pragma: no cover - compiled
    """Raster cell of every pose, as the reference's ``_bin_keys`` / ``heading_bins``.

    ``ix, iy`` (out) are ``floor(x / bin_xy_m)`` shifted to start at 0; ``it`` (out) is
    ``min(floor((wrap(theta) + pi) * scale), nt - 1)`` with ``scale = nt / (2 pi)`` computed by
    the caller. Returns ``(nx, ny)``.
    """
    n = poses.shape[0]
    mx = np.int64(0)
    my = np.int64(0)
    for i in range(n):
        a = np.int64(np.floor(poses[i, 0] / bin_xy_m))
        b = np.int64(np.floor(poses[i, 1] / bin_xy_m))
        ix[i] = a
        iy[i] = b
        if i == 0 or a < mx:
            mx = a
        if i == 0 or b < my:
            my = b
        k = np.int64(np.floor((_wrap(poses[i, 2]) + np.pi) * scale))
        it[i] = min(k, nt - 1)
    nx = np.int64(0)
    ny = np.int64(0)
    for i in range(n):
        ix[i] -= mx
        iy[i] -= my
        nx = max(nx, ix[i] + 1)
        ny = max(ny, iy[i] + 1)
    return nx, ny


@numba.njit(cache=True, nogil=True)
def nonzero_mass(mass):  # pragma: no cover - compiled
    """``mass[mass > 0]`` (raster order)."""
    k = 0
    for c in range(mass.shape[0]):
        if mass[c] > 0:
            k += 1
    out = np.empty(k)
    k = 0
    for c in range(mass.shape[0]):
        if mass[c] > 0:
            out[k] = mass[c]
            k += 1
    return out


@numba.njit(cache=True, nogil=True)
def _label_components_flood(occupied, ny, nx, nt, wrap_t, lab):  # pragma: no cover - compiled
    """`label_components` for any ``nt``, cell by cell: its fallback for ``nt > 64`` and its reference in the tests.

    A flood fill from each unlabelled occupied cell in C order; the stack holds each cell's
    coordinates beside its index, so no visit divides to find them (a cell is pushed once, when
    it is labelled).
    """
    size = ny * nx * nt
    stack = np.empty((size, 3), dtype=np.int64)
    n = 0
    for y0 in range(ny):
        for x0 in range(nx):
            for t0 in range(nt):
                c0 = (y0 * nx + x0) * nt + t0
                if not occupied[c0] or lab[c0] != 0:
                    continue
                n += 1
                lab[c0] = n
                stack[0, 0] = y0
                stack[0, 1] = x0
                stack[0, 2] = t0
                top = 1
                while top > 0:
                    top -= 1
                    y = stack[top, 0]
                    x = stack[top, 1]
                    t = stack[top, 2]
                    for yy in range(max(y - 1, 0), min(y + 2, ny)):
                        for xx in range(max(x - 1, 0), min(x + 2, nx)):
                            row = (yy * nx + xx) * nt
                            for dt in range(-1, 2):
                                tt = t + dt
                                if tt < 0:
                                    if not wrap_t:
                                        continue
                                    tt += nt
                                elif tt >= nt:
                                    if not wrap_t:
                                        continue
                                    tt -= nt
                                cc = row + tt
                                if occupied[cc] and lab[cc] == 0:
                                    lab[cc] = n
                                    stack[top, 0] = yy
                                    stack[top, 1] = xx
                                    stack[top, 2] = tt
                                    top += 1
    return n


@intrinsic
def _ctz(typingctx, v):  # pragma: no cover - compiled
    """Trailing zero bits of an unsigned integer (the bit width for 0): one ``tzcnt``."""
    if not isinstance(v, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], ir.Constant(ir.IntType(1), 0))

    return v(v), codegen


@intrinsic
def _popcount(typingctx, v):  # pragma: no cover - compiled
    """Set bits of an unsigned integer: one ``popcnt``."""
    if not isinstance(v, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return v(v), codegen


@numba.njit(cache=True, nogil=True)
def label_components(occupied, ny, nx, nt, wrap_t, lab):  # pragma: no cover - compiled
    """Connected components of the occupied cells of a ``(ny, nx, nt)`` raster (flat, C order).

    26-neighbourhood; with ``wrap_t`` the heading axis is circular. ``lab`` (out, zeroed) gets
    ``1..n`` for occupied cells and is not written elsewhere; components are numbered in the order
    of their first cell in C order, which is the numbering ``scipy.ndimage.label`` plus the
    reference's seam merge produce. Returns ``n``. The same ``lab`` and ``n`` as the cell-by-cell
    flood fill `_label_components_flood`, which this calls for ``nt > 64``.

    Runs of headings, not cells: each ``(y, x)`` column's occupied headings are an ``nt``-bit mask,
    and its maximal runs of set bits are its segments (with ``wrap_t`` a run through ``nt - 1`` and
    one through ``0`` are one segment). Two runs of one column never touch; segments of 8-neighbour
    columns touch when one meets the other's heading dilation ``m | m << 1 | m >> 1`` (rotations on
    the ring with ``wrap_t``). One scan in C order joins each column's segments to the touching ones
    of the columns already seen, ``(y - 1, x - 1 .. x + 1)`` and ``(y, x - 1)`` (union-find whose
    links point to lower segments, so a root is the first segment of its set). Segments are stored
    in column order and, in a column, by their lowest heading: numbering the roots in segment order
    numbers the components by their first cell. With ``nt <= 2`` the wrap adds no neighbour
    (every heading touches every other), as in the flood fill.
    """
    if nt > 64:
        return _label_components_flood(occupied, ny, nx, nt, wrap_t, lab)
    if ny <= 0 or nx <= 0 or nt <= 0:
        return 0
    ncol = ny * nx
    zero = np.uint64(0)
    one = np.uint64(1)
    top = np.uint64(nt - 1)
    full = ~zero if nt == 64 else (one << np.uint64(nt)) - one
    ring = nt > 2 and bool(wrap_t)
    cap = ncol * ((nt + 1) // 2)  # at most ceil(nt / 2) runs in a column
    seg_m = np.empty(cap, dtype=np.uint64)  # the segment's headings
    parent = np.empty(cap, dtype=np.int64)  # parent[s] <= s
    col_m = np.empty(ncol, dtype=np.uint64)  # the column's headings
    col_first = np.empty(ncol, dtype=np.int64)  # its first segment
    col_wlo = np.empty(ncol, dtype=np.int64)  # where its wrapping segment's top part starts, nt if none
    nseg = 0
    for y in range(ny):
        for x in range(nx):
            col = y * nx + x
            base = col * nt
            m = zero
            for t in range(nt):
                m |= np.uint64(occupied[base + t] != 0) << np.uint64(t)
            col_m[col] = m
            first = nseg
            col_first[col] = first
            col_wlo[col] = nt
            r = m
            while r != zero:
                run = ((r + (r & (~r + one))) ^ r) & r  # the lowest run of r
                seg_m[nseg] = run
                parent[nseg] = nseg
                nseg += 1
                r ^= run
            if ring and nseg - first > 1 and (m & one) != zero and (m >> top) != zero:
                nseg -= 1  # the last run (up to nt - 1) continues the first (from 0)
                seg_m[first] |= seg_m[nseg]
                col_wlo[col] = np.int64(_ctz(seg_m[nseg]))
            for s in range(first, nseg):
                sm = seg_m[s]
                if ring:
                    d = sm | ((sm << one) & full) | (sm >> one) | (sm >> top) | ((sm & one) << top)
                else:
                    d = sm | ((sm << one) & full) | (sm >> one)
                rs = s  # the root of s's set
                for k in range(4):
                    if k < 3:
                        if y == 0 or x + k == 0 or x + k > nx:
                            continue
                        q = col - nx - 1 + k
                    else:
                        if x == 0:
                            continue
                        q = col - 1
                    mq = col_m[q]
                    tm = mq & d  # q's headings that touch s
                    if tm == zero:
                        continue
                    q0 = col_first[q]
                    wlo = col_wlo[q]
                    starts = mq & ~(mq << one)
                    while True:
                        # o: the segment of q's lowest touching heading b (its run's rank among q's runs)
                        b = np.uint64(_ctz(tm))
                        if np.int64(b) >= wlo:
                            o = q0
                        else:
                            o = q0 + np.int64(_popcount(starts & (((one << b) << one) - one))) - 1
                        tm &= ~seg_m[o]
                        ro = parent[o]
                        if ro != rs:
                            while parent[ro] != ro:
                                parent[ro] = parent[parent[ro]]  # path halving
                                ro = parent[ro]
                            if ro < rs:
                                parent[rs] = ro
                                rs = ro
                            elif rs < ro:
                                parent[ro] = rs
                        if tm == zero:
                            break
    # num[s]: the component number of segment s. A root is the first segment of its set, and the
    # parent of any other segment comes before it, so its number is already known.
    num = np.empty(nseg, dtype=np.int64)
    n = 0
    for s in range(nseg):
        p = parent[s]
        if p == s:
            n += 1
            num[s] = n
        else:
            num[s] = num[p]
    for col in range(ncol):
        m = col_m[col]
        starts = m & ~(m << one)
        first = col_first[col]
        wlo = col_wlo[col]
        base = col * nt
        r = m
        while r != zero:
            b = np.uint64(_ctz(r))
            if np.int64(b) >= wlo:
                k = num[first]
            else:
                k = num[first + np.int64(_popcount(starts & (((one << b) << one) - one))) - 1]
            lab[base + np.int64(b)] = k
            r &= r - one
    return n


@numba.njit(cache=True, nogil=True)
def cluster_sums(labels, n, poses, sin_th, cos_th, w):  # pragma: no cover - compiled
    """First pass of ``cluster_stats``: per cluster the count, weight, ``ww``-weighted sums of
    ``x``, ``y``, ``sin``, ``cos`` (``ww`` = the weight, or ``1 / count`` in a zero-weight
    cluster), in particle order. Returns ``(count, weight, wsum, sums (n, 4))``."""
    count = np.zeros(n, dtype=np.int64)
    weight = np.zeros(n)
    for i in range(labels.shape[0]):
        k = labels[i]
        if k >= 0:
            count[k] += 1
            weight[k] += w[i]
    sums = np.zeros((n, 4))
    for i in range(labels.shape[0]):
        k = labels[i]
        if k < 0:
            continue
        ww = w[i] if weight[k] > 0 else 1.0 / max(count[k], 1)
        sums[k, 0] += ww * poses[i, 0]
        sums[k, 1] += ww * poses[i, 1]
        sums[k, 2] += ww * sin_th[i]
        sums[k, 3] += ww * cos_th[i]
    wsum = np.empty(n)
    for k in range(n):
        wsum[k] = weight[k] if weight[k] > 0 else 1.0
    return count, weight, wsum, sums


@numba.njit(cache=True, nogil=True)
def cluster_covariances(labels, n, poses, w, count, weight, wsum, mean):  # pragma: no cover - compiled
    """Second pass of ``cluster_stats``: ``cov (n, 3, 3)`` about ``mean`` (wrapped heading residuals)."""
    acc = np.zeros((n, 6))
    r = np.empty(3)
    for i in range(labels.shape[0]):
        k = labels[i]
        if k < 0:
            continue
        ww = w[i] if weight[k] > 0 else 1.0 / max(count[k], 1)
        r[0] = poses[i, 0] - mean[k, 0]
        r[1] = poses[i, 1] - mean[k, 1]
        r[2] = _wrap(poses[i, 2] - mean[k, 2])
        j = 0
        for a in range(3):
            for b in range(a, 3):
                acc[k, j] += ww * r[a] * r[b]
                j += 1
    cov = np.empty((n, 3, 3))
    for k in range(n):
        j = 0
        for a in range(3):
            for b in range(a, 3):
                v = acc[k, j] / wsum[k]
                cov[k, a, b] = v
                cov[k, b, a] = v
                j += 1
    return cov


def heading_scale(bin_theta_rad: float) -> tuple[int, float]:
    """``(nt, nt / (2 pi))`` of the reference's ``heading_bins``."""
    nt = max(1, round(2.0 * math.pi / bin_theta_rad))
    return nt, nt / (2.0 * math.pi)


# ------------------------------------------------------------------ fused stages of the summary
# Each replaces a chain of the kernels above and the NumPy glue between them with one call, with the same
# operations in the same order (so the same bits); `filters.localization.belief.summarize` uses them.


@numba.njit(cache=True, nogil=True)
def transposed_in_limit(poses, limit, out):  # pragma: no cover - compiled
    """``out (3, N)`` = ``poses.T`` (a copy) and whether every ``|x|, |y| < limit`` and every ``|theta| < inf``
    (the reference's ``(np.abs(poses) < (limit, limit, inf)).all()``: False for NaN)."""
    ok = True
    for i in range(poses.shape[0]):
        x = poses[i, 0]
        y = poses[i, 1]
        t = poses[i, 2]
        out[0, i] = x
        out[1, i] = y
        out[2, i] = t
        if not (abs(x) < limit and abs(y) < limit and abs(t) < np.inf):
            ok = False
    return ok


@numba.njit(cache=True, nogil=True)
def finite_non_negative_max(w):  # pragma: no cover - compiled
    """``(all finite and >= 0, max)`` of ``w`` (``max`` is meaningful only when the first is True)."""
    m = 0.0
    for i in range(w.shape[0]):
        v = w[i]
        if not (v >= 0.0 and v < np.inf):
            return False, 0.0
        if v > m:
            m = v
    return True, m


@numba.njit(cache=True, nogil=True, inline="always")
def _fits(nx, ny, nt, max_cells):  # pragma: no cover - compiled
    """``nx * ny * nt <= max_cells`` without forming a product that can overflow int64 (a cloud 1e9 m wide
    has more than 2**63 cells of 0.5 m; ``summarize`` takes poses up to 1e15 m)."""
    return nx <= max_cells and ny <= max_cells and nx * ny <= max_cells // nt


@numba.njit(cache=True, nogil=True, inline="always")
def _raster_mass(poses, w, bin_xy_m, nt, scale, max_cells):  # pragma: no cover - compiled
    """``(cell (N,), mass, count, nx, ny, fits)``: `raster_bins`, then the flat cell ``(iy nx + ix) nt + it`` of
    each particle, and per cell the weights ``w`` summed in particle order (``np.bincount``'s order) and the
    particles counted; empty ``mass`` and ``count`` and ``fits = False`` when the raster would exceed
    ``max_cells``."""
    n = poses.shape[0]
    ix = np.empty(n, dtype=np.int64)
    iy = np.empty(n, dtype=np.int64)
    it = np.empty(n, dtype=np.int64)
    nx, ny = raster_bins(poses, bin_xy_m, nt, scale, ix, iy, it)
    cell = np.empty(n, dtype=np.int64)
    if not _fits(nx, ny, nt, max_cells):
        return cell, np.empty(0), np.empty(0, dtype=np.int64), nx, ny, False
    mass = np.zeros(nx * ny * nt)
    count = np.zeros(nx * ny * nt, dtype=np.int64)
    for i in range(n):
        c = (iy[i] * nx + ix[i]) * nt + it[i]
        cell[i] = c
        mass[c] += w[i]
        count[c] += 1
    return cell, mass, count, nx, ny, True


@numba.njit(cache=True, nogil=True)
def entropy_masses(poses, w, bin_xy_m, nt, scale, max_cells):  # pragma: no cover - compiled
    """The nonzero raster masses of ``histogram_entropy`` in raster order (`_raster_mass`, then `nonzero_mass`);
    ``(masses, True)``, or ``(empty, False)`` when the raster would exceed ``max_cells``."""
    _, mass, _, _, _, fits = _raster_mass(poses, w, bin_xy_m, nt, scale, max_cells)
    if not fits:
        return mass, False
    return nonzero_mass(mass), True


@numba.njit(cache=True, nogil=True)
def cluster_raster(poses, w, bin_m, nt, scale, max_cells):  # pragma: no cover - compiled
    """The raster of ``cluster_labels``: ``(cell (N,), mass, count, nx, ny, held, fits)`` with ``cell[i]`` the
    flat raster cell ``(iy nx + ix) nt + it`` of particle ``i``, the cells' weight ``mass`` and particle
    ``count`` (`_raster_mass`), the number ``held`` of cells with particles, and ``fits = False`` (and
    empty arrays) when the raster would exceed ``max_cells``."""
    cell, mass, count, nx, ny, fits = _raster_mass(poses, w, bin_m, nt, scale, max_cells)
    held = 0
    for c in range(count.shape[0]):
        if count[c] > 0:
            held += 1
    return cell, mass, count, nx, ny, held, fits


@numba.njit(cache=True, nogil=True)
def cell_labels(mass, count, threshold, ny, nx, nt, cell):  # pragma: no cover - compiled
    """``(labels (N,), n)`` of ``cluster_labels`` from `cluster_raster`'s output: a cell is occupied when it
    holds particles and ``mass >= threshold`` (``threshold`` -inf: any cell with particles), its components
    are `label_components`' (heading circular when ``nt > 2``), and particle ``i`` gets its cell's component
    ``- 1`` (-1: in no cluster)."""
    size = ny * nx * nt
    occupied = np.empty(size, dtype=np.bool_)
    for c in range(size):
        occupied[c] = count[c] > 0 and mass[c] >= threshold
    lab = np.zeros(size, dtype=np.int64)
    n = label_components(occupied, ny, nx, nt, nt > 2, lab)
    out = np.empty(cell.shape[0], dtype=np.int64)
    for i in range(cell.shape[0]):
        out[i] = lab[cell[i]] - 1
    return out, n


@numba.njit(cache=True, nogil=True)
def group_order(labels, n_groups):  # pragma: no cover - compiled
    """``(order, starts)`` of labels in ``0 .. n_groups - 1``: ``order`` = ``np.argsort(labels, kind="stable")``
    (a counting sort: by label, then by index) and ``starts`` = ``np.searchsorted(labels[order],
    np.arange(n_groups + 1))``, so group ``k``'s members are ``order[starts[k]:starts[k + 1]]``."""
    starts = np.zeros(n_groups + 1, dtype=np.int64)
    for i in range(labels.shape[0]):
        starts[labels[i] + 1] += 1
    for k in range(n_groups):
        starts[k + 1] += starts[k]
    fill = starts[:-1].copy()
    order = np.empty(labels.shape[0], dtype=np.int64)
    for i in range(labels.shape[0]):
        k = labels[i]
        order[fill[k]] = i
        fill[k] += 1
    return order, starts


@numba.njit(cache=True, nogil=True)
def hypothesis_order(cw, min_weight):  # pragma: no cover - compiled
    """The clusters that are hypotheses, heaviest first: the indices ``k`` with ``cw[k] >= min_weight - 1e-12`` and
    ``cw[k] > 0``, in the order of a stable sort of ``-cw`` (ties: lower index first), as ``summarize``'s NumPy
    code picks them. An insertion sort for the few dozen a summary usually keeps; a stable merge sort beyond 64
    (``cluster_min_weight`` 0 keeps every cluster with weight)."""
    order = np.empty(cw.shape[0], dtype=np.int64)
    n = 0
    lo = min_weight - 1e-12
    for k in range(cw.shape[0]):
        v = cw[k]
        if v >= lo and v > 0.0:
            order[n] = k
            n += 1
    kept = order[:n]
    if n > 64:
        return kept[np.argsort(-cw[kept], kind="mergesort")]
    for i in range(1, n):
        k = kept[i]
        v = cw[k]
        j = i
        while j > 0 and cw[kept[j - 1]] < v:
            kept[j] = kept[j - 1]
            j -= 1
        kept[j] = k
    return kept
