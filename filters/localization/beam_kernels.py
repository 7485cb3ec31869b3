"""One compiled pass that turns an update's scans into the beams of a `filters.localization.likelihood_field.BeamSet`.

`LikelihoodFieldModel.beams` (the numba backend) calls `beam_parts` instead of the NumPy chain of
`filters.localization.likelihood_field.beams_reference` (``select_beams``, ``beam_endpoints``,
``count_detections``, ``negative_beams``, ``NegativeEvidenceConfig.sample_ranges``): about fifty small
array calls per update. The contract is the reference's arrays *bit for bit*: the same selections (NumPy's
``linspace`` and ``round`` written out), the same IEEE operations in the same order, and ``math.cos`` /
``math.sin``, the C library's, which NumPy's float64 ``cos`` / ``sin`` also call (``tests/test_beam_kernels.py``
compares the two on random scans, and the episode tests would see any difference).
"""

from __future__ import annotations

import math

import numba
import numpy as np


@numba.njit(cache=True, nogil=True)
def spread_picks(count, max_beams):  # pragma: no cover - compiled
    """``np.round(np.linspace(0.0, count - 1, max_beams)).astype(np.int64)`` for ``count > max_beams >= 1``:
    ``i * step`` with ``step = (count - 1) / (max_beams - 1)``, the last exactly ``count - 1``, rounded half to
    even."""
    out = np.empty(max_beams, dtype=np.int64)
    if max_beams == 1:
        out[0] = 0
        return out
    stop = float(count - 1)
    step = stop / float(max_beams - 1)
    for i in range(max_beams - 1):
        out[i] = np.int64(np.rint(float(i) * step + 0.0))
    out[max_beams - 1] = np.int64(np.rint(stop))
    return out


@numba.njit(cache=True, nogil=True)
def select(candidates, stride, max_beams):  # pragma: no cover - compiled
    """`filters.localization.likelihood_field.select_beams`: every ``stride``-th beam that is a candidate, then at
    most ``max_beams`` of them evenly spread (0 = all)."""
    idx = np.empty(candidates.shape[0], dtype=np.int64)
    k = 0
    for i in range(0, candidates.shape[0], stride):
        if candidates[i]:
            idx[k] = i
            k += 1
    if max_beams and k > max_beams:
        picks = spread_picks(k, max_beams)
        out = np.empty(max_beams, dtype=np.int64)
        for j in range(max_beams):
            out[j] = idx[picks[j]]
        return out
    return idx[:k].copy()


@numba.njit(cache=True, nogil=True, inline="always")
def _endpoint(r, a, sx, sy, st):  # pragma: no cover - compiled
    """`filters.robot_data.scans.beam_endpoints` of one beam: ``r cos(a + st) (+ sx)``, ``r sin(a + st) (+ sy)``,
    with no ``+ st`` when ``st == 0`` and no shift when ``sx == sy == 0``, as there."""
    if st != 0.0:
        a = a + st
    x = r * math.cos(a)
    y = r * math.sin(a)
    if sx != 0.0 or sy != 0.0:
        x = x + sx
        y = y + sy
    return x, y


@numba.njit(cache=True, nogil=True, inline="always")
def _negative_points(ranges, angles, labels, r_max, pose, max_beams, margin, step):  # pragma: no cover - compiled
    """``(nx, ny, n_starts)`` of `beam_parts`: the negative-evidence beams (unlabelled returns with unlabelled
    neighbours, at most ``max_beams`` evenly spread; none when ``max_beams`` is 0) sampled ``margin`` short of the
    return and then every ``step`` towards the robot (`NegativeEvidenceConfig.sample_ranges`), their end points
    beam after beam and where each beam with points starts; empty and ``[0]`` when no point is sampled."""
    ns = ranges.shape[0]
    if ns == 0 or max_beams == 0:
        return np.empty(0), np.empty(0), np.zeros(1, dtype=np.int64)
    free = np.empty(ns, dtype=np.bool_)
    for i in range(ns):
        near = labels[i] > 0 or (i > 0 and labels[i - 1] > 0) or (i + 1 < ns and labels[i + 1] > 0)
        free[i] = not near and ranges[i] < r_max
    beams = select(free, 1, max_beams)
    counts = np.empty(beams.shape[0], dtype=np.int64)
    first = np.empty(beams.shape[0])
    total = 0
    kept = 0
    for b in range(beams.shape[0]):
        f = ranges[beams[b]] - margin
        first[b] = f
        steps = np.floor((f - step) / step + 1e-9)
        counts[b] = np.int64(steps + 1.0) if f >= step else 0
        total += counts[b]
        if counts[b] > 0:
            kept += 1
    if total == 0:
        return np.empty(0), np.empty(0), np.zeros(1, dtype=np.int64)
    nx = np.empty(total)
    ny = np.empty(total)
    n_starts = np.zeros(kept + 1, dtype=np.int64)
    q = 0
    kb = 0
    for b in range(beams.shape[0]):
        if counts[b] == 0:
            continue
        for k in range(counts[b]):
            nx[q], ny[q] = _endpoint(first[b] - step * float(k), angles[beams[b]], pose[0], pose[1], pose[2])
            q += 1
        kb += 1
        n_starts[kb] = q
    return nx, ny, n_starts


@numba.njit(cache=True, nogil=True)
def beam_parts(
    l_ranges, l_angles, l_min, l_max, l_pose, l_stride, l_beams,
    s_ranges, s_angles, s_labels, s_max, s_pose, s_stride, s_beams,
    neg_beams, neg_margin, neg_step,
):  # fmt: skip  # pragma: no cover - compiled
    """The arrays of a `BeamSet`: ``(lx, ly, table, n_lidar, n_semantic, n_detections, nx, ny, n_starts)``.

    Lidar (empty ``l_ranges``: none): the returns ``l_min <= r < l_max``, selected by ``l_stride`` / ``l_beams``.
    Semantic (empty ``s_ranges``: none): the labelled returns (``label > 0``, ``r < s_max``) selected likewise, with
    their labels as the field index; the detections (runs of one label); and, with ``neg_beams > 0``, the
    negative-evidence beams (unlabelled returns with unlabelled neighbours, at most ``neg_beams`` evenly spread)
    sampled ``neg_margin`` short of the return and then every ``neg_step`` towards the robot. ``nx``, ``ny`` are
    empty and ``n_starts`` is ``[0]`` when no point is sampled. Poses are ``(x m, y m, theta rad)`` arrays."""
    nl = l_ranges.shape[0]
    valid = np.empty(nl, dtype=np.bool_)
    for i in range(nl):
        valid[i] = l_ranges[i] < l_max and l_ranges[i] >= l_min
    li = select(valid, l_stride, l_beams)
    ns = s_ranges.shape[0]
    labelled = np.empty(ns, dtype=np.bool_)
    for i in range(ns):
        labelled[i] = s_labels[i] > 0 and s_ranges[i] < s_max
    si = select(labelled, s_stride, s_beams)
    n_l = li.shape[0]
    n_s = si.shape[0]
    lx = np.empty(n_l + n_s)
    ly = np.empty(n_l + n_s)
    table = np.zeros(n_l + n_s, dtype=np.int64)
    for j in range(n_l):
        lx[j], ly[j] = _endpoint(l_ranges[li[j]], l_angles[li[j]], l_pose[0], l_pose[1], l_pose[2])
    for j in range(n_s):
        i = si[j]
        lx[n_l + j], ly[n_l + j] = _endpoint(s_ranges[i], s_angles[i], s_pose[0], s_pose[1], s_pose[2])
        table[n_l + j] = s_labels[i]
    n_det = 0
    for i in range(ns):
        lab = s_labels[i] if labelled[i] else 0
        if lab > 0 and (i == 0 or lab != (s_labels[i - 1] if labelled[i - 1] else 0)):
            n_det += 1
    nx, ny, n_starts = _negative_points(s_ranges, s_angles, s_labels, s_max, s_pose, neg_beams, neg_margin, neg_step)
    return lx, ly, table, n_l, n_s, n_det, nx, ny, n_starts
