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
    return _bins(poses, bin_xy_m, nt, scale, ix, iy, it, 0, 0.0, it)


@numba.njit(cache=True, nogil=True, inline="always")
def _bins(poses, bin_xy_m, nt, scale, ix, iy, it, nt2, scale2, it2):  # pragma: no cover - compiled
    """`raster_bins`, and with ``nt2 > 0`` the headings' bins of a second raster of the same cells into ``it2``
    (``nt2`` headings, ``scale2``) in the same pass."""
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
        t = _wrap(poses[i, 2]) + np.pi
        it[i] = min(np.int64(np.floor(t * scale)), nt - 1)
        if nt2 > 0:
            it2[i] = min(np.int64(np.floor(t * scale2)), nt2 - 1)
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
def cluster_members(labels, n):  # pragma: no cover - compiled
    """``(order, starts)``: the particles of each cluster ``0 .. n - 1`` in index order, cluster ``k``'s being
    ``order[starts[k]:starts[k + 1]]`` (a counting sort; label -1, no cluster, is left out). ``labels`` must lie in
    ``-1 .. n - 1`` (not checked: a larger label writes out of bounds). With every label in
    ``0 .. n - 1``, ``order`` is ``np.argsort(labels, kind="stable")`` and ``starts`` is
    ``np.searchsorted(labels[order], np.arange(n + 1))``."""
    starts = np.zeros(n + 1, dtype=np.int64)
    for i in range(labels.shape[0]):
        if labels[i] >= 0:
            starts[labels[i] + 1] += 1
    for k in range(n):
        starts[k + 1] += starts[k]
    fill = starts[:-1].copy()
    order = np.empty(starts[n], dtype=np.int64)
    for i in range(labels.shape[0]):
        k = labels[i]
        if k >= 0:
            order[fill[k]] = i
            fill[k] += 1
    return order, starts


@numba.njit(cache=True, nogil=True)
def cluster_sums(labels, n, poses, sin_th, cos_th, w):  # pragma: no cover - compiled
    """First pass of ``cluster_stats``: per cluster the count, weight, ``ww``-weighted sums of
    ``x``, ``y``, ``sin``, ``cos`` (``ww`` = the weight, or ``1 / count`` in a zero-weight
    cluster), each summed in particle order. Returns ``(count, weight, wsum, sums (n, 4), order, starts)``, the last
    two `cluster_members`' (for `cluster_covariances`).

    A cluster at a time, its sums in registers: the same additions in the same order as adding each particle into
    its cluster's slot, without a load and a store per addition."""
    order, starts = cluster_members(labels, n)
    count = np.empty(n, dtype=np.int64)
    weight = np.empty(n)
    wsum = np.empty(n)
    sums = np.empty((n, 4))
    for k in range(n):
        lo = starts[k]
        hi = starts[k + 1]
        wk = 0.0
        for j in range(lo, hi):
            wk += w[order[j]]
        count[k] = hi - lo
        weight[k] = wk
        positive = wk > 0
        each = 1.0 / max(hi - lo, 1)
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        s3 = 0.0
        for j in range(lo, hi):
            i = order[j]
            ww = w[i] if positive else each
            s0 += ww * poses[i, 0]
            s1 += ww * poses[i, 1]
            s2 += ww * sin_th[i]
            s3 += ww * cos_th[i]
        sums[k, 0] = s0
        sums[k, 1] = s1
        sums[k, 2] = s2
        sums[k, 3] = s3
        wsum[k] = wk if positive else 1.0
    return count, weight, wsum, sums, order, starts


@numba.njit(cache=True, nogil=True)
def cluster_covariances(order, starts, poses, w, count, weight, wsum, mean):  # pragma: no cover - compiled
    """Second pass of ``cluster_stats``: ``cov (n, 3, 3)`` about ``mean`` (wrapped heading residuals): each cluster's
    ``ww``-weighted residual products (`cluster_sums`' ``ww``), its members ``order[starts[k]:starts[k + 1]]``
    summed in particle order in registers, divided by its ``wsum``."""
    n = starts.shape[0] - 1
    cov = np.empty((n, 3, 3))
    for k in range(n):
        positive = weight[k] > 0
        each = 1.0 / max(count[k], 1)
        mx = mean[k, 0]
        my = mean[k, 1]
        mt = mean[k, 2]
        a00 = 0.0
        a01 = 0.0
        a02 = 0.0
        a11 = 0.0
        a12 = 0.0
        a22 = 0.0
        for j in range(starts[k], starts[k + 1]):
            i = order[j]
            ww = w[i] if positive else each
            r0 = poses[i, 0] - mx
            r1 = poses[i, 1] - my
            r2 = _wrap(poses[i, 2] - mt)
            a00 += ww * r0 * r0
            a01 += ww * r0 * r1
            a02 += ww * r0 * r2
            a11 += ww * r1 * r1
            a12 += ww * r1 * r2
            a22 += ww * r2 * r2
        d = wsum[k]
        cov[k, 0, 0] = a00 / d
        cov[k, 1, 1] = a11 / d
        cov[k, 2, 2] = a22 / d
        v = a01 / d
        cov[k, 0, 1] = v
        cov[k, 1, 0] = v
        v = a02 / d
        cov[k, 0, 2] = v
        cov[k, 2, 0] = v
        v = a12 / d
        cov[k, 1, 2] = v
        cov[k, 2, 1] = v
    return cov


def heading_scale(bin_theta_rad: float) -> tuple[int, float]:
    """``(nt, nt / (2 pi))`` of the reference's ``heading_bins``."""
    nt = max(1, round(2.0 * math.pi / bin_theta_rad))
    return nt, nt / (2.0 * math.pi)


# ------------------------------------------------------------------ fused stages of the summary
# Each replaces a chain of the kernels above and the NumPy glue between them with one call, with the same
# operations in the same order (so the same bits). `filters.localization.belief.summarize` calls them through the four
# `summary_*` kernels at the end of this module, and its fallbacks for clouds too wide for the rasters directly.


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
    """``(cell (N,), mass, count, nx, ny, fits)``: `raster_bins`, then `_cell_masses`."""
    n = poses.shape[0]
    ix = np.empty(n, dtype=np.int64)
    iy = np.empty(n, dtype=np.int64)
    it = np.empty(n, dtype=np.int64)
    nx, ny = raster_bins(poses, bin_xy_m, nt, scale, ix, iy, it)
    cell, mass, count, fits = _cell_masses(ix, iy, it, nx, ny, nt, w, max_cells)
    return cell, mass, count, nx, ny, fits


@numba.njit(cache=True, nogil=True, inline="always")
def _cell_masses(ix, iy, it, nx, ny, nt, w, max_cells):  # pragma: no cover - compiled
    """``(cell (N,), mass, count, fits)``: the flat cell ``(iy nx + ix) nt + it`` of each particle (`raster_bins`'
    ``ix, iy, it`` and ``nx, ny``), and per cell the weights ``w`` summed in particle order (``np.bincount``'s order)
    and the particles counted; empty ``mass`` and ``count`` and ``fits = False`` when the raster would exceed
    ``max_cells``."""
    n = ix.shape[0]
    cell = np.empty(n, dtype=np.int64)
    if not _fits(nx, ny, nt, max_cells):
        return cell, np.empty(0), np.empty(0, dtype=np.int64), False
    mass = np.zeros(nx * ny * nt)
    count = np.zeros(nx * ny * nt, dtype=np.int64)
    for i in range(n):
        c = (iy[i] * nx + ix[i]) * nt + it[i]
        cell[i] = c
        mass[c] += w[i]
        count[c] += 1
    return cell, mass, count, True


@numba.njit(cache=True, nogil=True, inline="always")
def _held(count):  # pragma: no cover - compiled
    """Cells with particles."""
    held = 0
    for c in range(count.shape[0]):
        if count[c] > 0:
            held += 1
    return held


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
    return cell, mass, count, nx, ny, _held(count), fits


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


# ------------------------------------------------------------------ the summary in four calls
# `filters.localization.belief.summarize` (numba backend) runs these four, with NumPy between them for what must stay
# NumPy's (module docstring): the weights' normalisation, the BLAS dot products and covariance, the entropy's logs and
# sum, the cluster threshold's sum, the means' arctan2. Each is the kernels above, one call for several.


@numba.njit(cache=True, nogil=True)
def summary_inputs(poses, w, limit, xyt, cos_th, sin_th):  # pragma: no cover - compiled
    """Before the weights are normalised: `transposed_in_limit` of ``poses`` into ``xyt`` ``(3, N)``, the headings'
    cos and sin into ``cos_th`` and ``sin_th`` (`filters.pose.cos_sin`'s, the C library's), and
    `finite_non_negative_max` of the raw weights ``w``. Returns ``(in_limit, weights_ok, largest)``."""
    in_limit = transposed_in_limit(poses, limit, xyt)
    for i in range(poses.shape[0]):  # `filters.pose.cos_sin`'s loop: a cached kernel calls only its own file's
        t = xyt[2, i]
        cos_th[i] = math.cos(t)  # LLVM makes the pair one sincos call
        sin_th[i] = math.sin(t)
    ok, largest = finite_non_negative_max(w)
    return in_limit, ok, largest


@numba.njit(cache=True, nogil=True)
def summary_rasters(
    poses, w, mx, my, mth, res, e_bin, e_nt, e_scale, c_bin, c_nt, c_scale, max_cells
):  # pragma: no cover - compiled
    """After the mean: `residuals` into ``res`` ``(3, N)``, `entropy_masses` (cells ``e_bin`` m, ``e_nt`` headings)
    and `cluster_raster` (``c_bin``, ``c_nt``) of the normalised weights ``w``, the positions binned once when the two
    rasters' cells are the same size. Returns ``(masses, e_fits, cell, mass, count, nx, ny, held, c_fits)``: the
    entropy raster's nonzero masses and whether it fit, then `cluster_raster`'s output."""
    residuals(poses, mx, my, mth, res)
    n = poses.shape[0]
    ix = np.empty(n, dtype=np.int64)
    iy = np.empty(n, dtype=np.int64)
    it = np.empty(n, dtype=np.int64)
    c_it = np.empty(n, dtype=np.int64)
    shared = c_bin == e_bin  # the same x and y bins: only the headings' differ
    nx, ny = _bins(poses, e_bin, e_nt, e_scale, ix, iy, it, c_nt if shared else 0, c_scale, c_it)
    _, e_mass, _, e_fits = _cell_masses(ix, iy, it, nx, ny, e_nt, w, max_cells)
    masses = nonzero_mass(e_mass) if e_fits else e_mass
    if not shared:
        nx, ny = raster_bins(poses, c_bin, c_nt, c_scale, ix, iy, c_it)
    cell, mass, count, c_fits = _cell_masses(ix, iy, c_it, nx, ny, c_nt, w, max_cells)
    return masses, e_fits, cell, mass, count, nx, ny, _held(count), c_fits


@numba.njit(cache=True, nogil=True)
def summary_clusters(mass, count, threshold, ny, nx, nt, cell, poses, sin_th, cos_th, w):  # pragma: no cover - compiled
    """`cell_labels` of `summary_rasters`' cluster raster, then `cluster_sums` of the clusters:
    ``(count, weight, wsum, sums, order, starts)``."""
    labels, n = cell_labels(mass, count, threshold, ny, nx, nt, cell)
    return cluster_sums(labels, n, poses, sin_th, cos_th, w)


@numba.njit(cache=True, nogil=True)
def summary_covariances(order, starts, poses, w, count, weight, wsum, mean, min_weight):  # pragma: no cover - compiled
    """`cluster_covariances` and `hypothesis_order` of the clusters: ``(cov (n, 3, 3), kept)``."""
    return cluster_covariances(order, starts, poses, w, count, weight, wsum, mean), hypothesis_order(weight, min_weight)
