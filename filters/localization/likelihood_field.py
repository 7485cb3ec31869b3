"""Likelihood-field measurement model for lidar and semantic pseudo-laser scans.

The standard likelihood-field model (Thrun et al., *Probabilistic Robotics* §6.4;
ROS AMCL's ``likelihood_field``), extended with one field per semantic class as in
paper 004 (Eq. 8-11):

* Each beam end point (from the sensor at its mounting pose ``scan.sensor_pose`` in the
  robot frame, default the robot centre) is projected into the map.
* ``d`` = distance from the end point's cell to the nearest *occupied* cell (lidar
  beams, Eq. 10) or to the nearest cell *of the beam's class* (labelled semantic
  beams, Eq. 11); ``d`` is capped at ``max_dist_m``.
* Per-beam likelihood ``p = z_hit * exp(-d^2 / (2 sigma_hit^2)) + z_rand / range_max``.
  It is evaluated in log space as ``logaddexp(log z_hit - d^2/(2 sigma^2), log(z_rand/range_max))``
  so it never underflows (finite whenever ``z_hit > 0`` or ``z_rand > 0``).
* End points outside the map get the *floor* ``log p(max_dist_m)``: the value of a
  beam as far from any obstacle as the cap allows, i.e. the random-measurement
  floor ``z_rand / range_max`` plus a Gaussian tail that is negligible for the
  defaults (``exp(-50)``). This is AMCL's choice as well.
* Beams at or beyond ``range_max`` (no return) or below a lidar's ``range_min_m`` (invalid)
  are skipped; semantic beams with
  label 0 (no object) contribute nothing.
* A scan's log-likelihood is the sum over the selected beams.
* Optionally (`NegativeEvidenceConfig`, off by default) unlabelled semantic beams count too: a
  pose from which the map puts an object on such a beam's ray, before its return, loses up to
  ``log(1 - p_detect)`` per beam (the object should have been detected), added to the semantic factor.

A semantic class with no cell in the map has distance ``inf`` everywhere, capped
to ``max_dist_m``: every particle gets the same floor value for such a beam, so
it does not change the *relative* weights (it carries no information).

Distances are between cell centres (exact Euclidean distance transform of the
occupied / class masks, ``scipy.ndimage.distance_transform_edt``), in metres.

Speed: per ``(lidar range_max, semantic range_max)`` pair the model precomputes
one table of ``log p`` per cell for the occupancy field and every class field, so
an update is one table look-up per particle and beam, done by the numba kernel
`log_likelihood_kernel`. `filters.localization.likelihood_reference` holds a pure
NumPy implementation of the same model, computed from the distance fields
without the tables, used to test the kernel.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import math
import weakref
from collections import OrderedDict
from dataclasses import dataclass, field

import numba
import numpy as np
from scipy import ndimage

from filters.localization.beam_kernels import beam_parts
from filters.localization.likelihood_reference import log_likelihood_terms_reference
from filters.mapping.grid import GridMap
from filters.numbers import MAX_LENGTH_M, is_int, is_real
from filters.pose import cos_sin
from filters.robot_data.scans import LaserScan, SemanticScan, beam_endpoints

MAX_BEAMS = 1_000_000
"""Largest beam count or stride a field config takes (no scan has more; 10**20 overflowed the compiled kernels)."""


@dataclass(frozen=True)
class LikelihoodFieldConfig:
    """Parameters of one likelihood field (lidar or semantic).

    Attributes:
        sigma_hit_m: std of the Gaussian hit score, metres (> 0, at most ``filters.numbers.MAX_LENGTH_M``).
        z_hit: weight of the hit component (>= 0).
        z_rand: weight of the uniform random-measurement component (>= 0); divided by the
            scan's ``range_max_m``. ``z_hit + z_rand`` must be > 0.
        max_dist_m: distances are capped here (metres, > 0); also the distance assumed
            for end points outside the map.
        beam_stride: use every ``beam_stride``-th beam of the scan (>= 1).
        max_beams: at most this many beams (evenly spread over the ones left after the
            stride and dropping no-return / unlabelled beams); 0 = no cap.
        tolerance_m: end points within this distance of the field's cells score as if on them (the hit
            score's distance is ``max(d - tolerance_m, 0)``; metres, >= 0; 0: off), so a map whose
            surfaces lie a cell or so off (a robot's map of identical places) moves no weight.
    """

    sigma_hit_m: float = 0.2
    z_hit: float = 0.95
    z_rand: float = 0.05
    max_dist_m: float = 2.0
    beam_stride: int = 1
    max_beams: int = 60
    tolerance_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("sigma_hit_m", "max_dist_m"):
            v = getattr(self, name)
            if not (is_real(v) and 0 < v <= MAX_LENGTH_M):
                raise ValueError(
                    f"LikelihoodFieldConfig.{name} must be a positive number of metres, at most {MAX_LENGTH_M:g}, "
                    f"got {v!r}"
                )
            object.__setattr__(self, name, float(v))
        for name in ("z_hit", "z_rand", "tolerance_m"):
            v = getattr(self, name)
            if not (is_real(v) and math.isfinite(v) and v >= 0):
                raise ValueError(f"LikelihoodFieldConfig.{name} must be a finite number >= 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        if not self.z_hit + self.z_rand > 0:
            raise ValueError("LikelihoodFieldConfig: z_hit + z_rand must be > 0")
        if not (is_int(self.beam_stride) and 1 <= self.beam_stride <= MAX_BEAMS):
            raise ValueError(
                f"LikelihoodFieldConfig.beam_stride must be an int in [1, {MAX_BEAMS:,}], got {self.beam_stride!r}"
            )
        if not (is_int(self.max_beams) and 0 <= self.max_beams <= MAX_BEAMS):
            raise ValueError(
                f"LikelihoodFieldConfig.max_beams must be an int in [0, {MAX_BEAMS:,}], got {self.max_beams!r}"
            )
        object.__setattr__(self, "beam_stride", int(self.beam_stride))
        object.__setattr__(self, "max_beams", int(self.max_beams))

    def log_p(self, dist_m: np.ndarray, range_max_m: float) -> np.ndarray:
        """``log p`` of beams whose end points lie ``dist_m`` from the field's cells (capped here)."""
        d = np.minimum(np.asarray(dist_m, dtype=np.float64), self.max_dist_m)
        if self.tolerance_m > 0:
            d = np.maximum(d - self.tolerance_m, 0.0)
        with np.errstate(divide="ignore"):
            log_hit = np.log(self.z_hit) - d * d / (2.0 * self.sigma_hit_m**2)
            log_rand = np.log(self.z_rand / range_max_m)
        return np.logaddexp(log_hit, log_rand)


@dataclass(frozen=True)
class NegativeEvidenceConfig:
    """Evidence from mapped objects the camera should have seen but did not (``p_detect = 0``: off).

    A semantic beam that returns from a surface at range ``r`` without a label says that no
    object lies on its ray before ``r``. The positive likelihood field takes nothing from such a
    beam, so a pose from which the map predicts an object where the camera sees a bare wall
    loses nothing (docs/relocalizer.md, "Negative evidence"). With ``p_detect > 0`` up to
    ``max_beams`` such beams (evenly spread; beams next to a labelled one are skipped, as their
    rays graze the detected object's edge) are each sampled at points ``margin_m`` short of the
    return and then every ``step_m`` back towards the robot (down to ``step_m``). Each point is
    looked up in a table of ``log(1 - p_detect * presence(d))``, ``d`` the distance (metres)
    from the point's cell to the nearest mapped object cell of *any* class, ``presence(d) = 1``
    for ``d <= radius_m`` and ``exp(-(d - radius_m)^2 / (2 sigma_m^2))`` beyond; off the map the
    value is 0. A beam adds the lowest value of its points (one object on the ray suffices), so
    a pose loses at most ``log(1 - p_detect)`` per beam, before the filter's tempering. The sum
    is added to the semantic factor.

    Attributes:
        p_detect: chance the filter assumes that a mapped object on the ray is detected, in
            ``[0, 1)``; 0 turns the evidence off (no beams are selected, nothing is computed).
        radius_m: points this close to an object cell count as on it (metres, >= 0).
        sigma_m: fall-off of ``presence`` beyond ``radius_m`` (metres, >= 0.001).
        step_m: spacing of the points along a beam (metres, >= 0.01).
        margin_m: the first point lies this far short of the return (metres, >= 0), so that a
            beam ending on a wall beside an object does not count as passing through it.
        max_beams: at most this many beams per scan (>= 1).
    """

    p_detect: float = 0.0
    radius_m: float = 0.0
    sigma_m: float = 0.07
    step_m: float = 0.15
    margin_m: float = 0.15
    max_beams: int = 8

    def __post_init__(self) -> None:
        p = self.p_detect
        if not (is_real(p) and 0.0 <= p < 1.0):
            raise ValueError(f"NegativeEvidenceConfig.p_detect must be a number in [0, 1), got {p!r}")
        object.__setattr__(self, "p_detect", float(p))
        for name, low in (("radius_m", 0.0), ("sigma_m", 1e-3), ("step_m", 0.01), ("margin_m", 0.0)):
            v = getattr(self, name)
            if not (is_real(v) and low <= v <= MAX_LENGTH_M):
                raise ValueError(
                    f"NegativeEvidenceConfig.{name} must be a number in [{low}, {MAX_LENGTH_M:g}] m, got {v!r}"
                )
            object.__setattr__(self, name, float(v))
        if not (is_int(self.max_beams) and 1 <= self.max_beams <= MAX_BEAMS):
            raise ValueError(
                f"NegativeEvidenceConfig.max_beams must be an int in [1, {MAX_BEAMS:,}], got {self.max_beams!r}"
            )
        object.__setattr__(self, "max_beams", int(self.max_beams))

    @property
    def enabled(self) -> bool:
        return self.p_detect > 0.0

    def log_q(self, dist_m: np.ndarray) -> np.ndarray:
        """``log(1 - p_detect * presence(d))`` for points ``dist_m`` from the nearest object cell."""
        d = np.asarray(dist_m, dtype=np.float64)
        over = np.maximum(d - self.radius_m, 0.0)
        presence = np.exp(-(over * over) / (2.0 * self.sigma_m**2))
        return np.log1p(-self.p_detect * presence)

    def sample_ranges(self, ranges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points of beams returning at ``ranges`` ``(B,)`` (metres): ``(counts (B,), r (S,))``,
        each beam's points ``r - margin_m``, then every ``step_m`` down to ``step_m`` (none if
        ``r - margin_m < step_m``), beam after beam."""
        first = np.asarray(ranges, dtype=np.float64) - self.margin_m
        steps = np.floor((first - self.step_m) / self.step_m + 1e-9)  # 1e-9: a step that is not exact in binary
        counts = np.where(first >= self.step_m, steps + 1, 0).astype(np.int64)
        ends = np.cumsum(counts)
        k = np.arange(int(ends[-1]) if counts.size else 0) - np.repeat(ends - counts, counts)
        return counts, np.repeat(first, counts) - self.step_m * k


NO_NEGATIVE_EVIDENCE = NegativeEvidenceConfig()
"""The default: negative evidence off (the model of paper 004)."""


def _negative_in_effect(negative: NegativeEvidenceConfig | None) -> NegativeEvidenceConfig:
    """``negative`` as a model uses it: None and every disabled config are `NO_NEGATIVE_EVIDENCE`
    (so they share one cached model). TypeError if it is not a `NegativeEvidenceConfig`."""
    if negative is None:
        return NO_NEGATIVE_EVIDENCE
    if not isinstance(negative, NegativeEvidenceConfig):
        raise TypeError(f"negative must be a NegativeEvidenceConfig, got {type(negative).__name__}")
    return negative if negative.enabled else NO_NEGATIVE_EVIDENCE


DEFAULT_SEMANTIC_FIELD = LikelihoodFieldConfig(sigma_hit_m=0.3, z_hit=0.8, z_rand=0.2, max_dist_m=2.0, max_beams=40)
"""Semantic defaults: wider Gaussian and a higher random floor than lidar, because
detections are less precise and false detections happen (paper 004 §3)."""


def table_codes(table: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(codes, values)`` with ``values[codes]`` the bytes of the float64 ``table`` (values told apart by their
    bits: ``-0.0`` and ``0.0`` are two values, so is every NaN payload), ``codes`` ``uint16`` if there are at
    most 65536 distinct values, else ``uint32``; both read-only."""
    bits, codes = np.unique(np.ascontiguousarray(table, dtype=np.float64).view(np.int64), return_inverse=True)
    codes = codes.reshape(-1).astype(np.uint16 if bits.size <= 1 << 16 else np.uint32)
    values = bits.view(np.float64)
    codes.setflags(write=False)
    values.setflags(write=False)
    return codes, values


def distance_field(mask: np.ndarray, resolution_m: float) -> np.ndarray:
    """``(H, W)`` float64 distance (metres) from each cell centre to the nearest ``True`` cell.

    ``inf`` everywhere if ``mask`` has no ``True`` cell.
    """
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return np.full(mask.shape, np.inf)
    return ndimage.distance_transform_edt(~mask, sampling=resolution_m).astype(np.float64)


def select_beams(candidates: np.ndarray, stride: int, max_beams: int) -> np.ndarray:
    """Indices of the beams to use: every ``stride``-th beam that is a candidate, then at
    most ``max_beams`` of them evenly spread (0 = all)."""
    idx = np.arange(0, candidates.size, stride)
    idx = idx[candidates[idx]]
    if max_beams and idx.size > max_beams:
        idx = idx[np.round(np.linspace(0.0, idx.size - 1, max_beams)).astype(np.int64)]
    return idx


def count_detections(semantic: SemanticScan) -> int:
    """Number of objects seen in a semantic scan: maximal runs of adjacent labelled
    beams that carry the same label (one detection box gives one run)."""
    lab = np.where(semantic.labelled, semantic.labels, 0)
    if lab.size == 0:
        return 0
    start = lab > 0
    start[1:] &= lab[1:] != lab[:-1]
    return int(start.sum())


_EMPTY_F = np.zeros(0)
_EMPTY_F.setflags(write=False)
_ZERO_START = np.zeros(1, np.int64)
_ZERO_START.setflags(write=False)
_NO_CODES = np.zeros(1, np.uint16)  # read-only, as `negative_codes`': one compiled signature of `window_kernel`
_NO_CODES.setflags(write=False)
_NO_VALUES = np.zeros(1)
_NO_VALUES.setflags(write=False)
_EMPTY_I = np.zeros(0, np.int64)
_EMPTY_I.setflags(write=False)
_ZERO_POSE = np.zeros(3)  # read-only, as the scans' sensor poses: one compiled signature of `beam_parts`
_ZERO_POSE.setflags(write=False)


def negative_beams(labels: np.ndarray, ranges: np.ndarray, range_max_m: float, max_beams: int) -> np.ndarray:
    """Indices of the beams `NegativeEvidenceConfig` samples: unlabelled returns (``ranges <
    range_max_m``) whose neighbours carry no label either, at most ``max_beams`` evenly spread."""
    lab = labels > 0
    near = lab.copy()
    near[1:] |= lab[:-1]
    near[:-1] |= lab[1:]
    return select_beams(~near & (ranges < range_max_m), 1, max_beams)


@dataclass(frozen=True, eq=False)
class BeamSet:
    """The beams of one update, in the robot frame, ready for the kernel.

    Attributes:
        lx, ly: ``(B,)`` end points in the robot frame, metres (lidar beams first).
        table: ``(B,)`` int64 field index per beam: 0 = occupancy, ``k + 1`` = class ``k``.
        n_lidar: number of lidar beams (the first ``n_lidar`` entries).
        n_semantic: number of labelled semantic beams (the rest).
        n_detections: objects seen in the semantic scan (see `count_detections`).
        lidar_range_max_m, semantic_range_max_m: range limits the log tables use.
        nx, ny: ``(S,)`` robot-frame points (metres) of the negative-evidence beams
            (`NegativeEvidenceConfig`), beam after beam; empty when it is off.
        n_starts: ``(n_negative + 1,)`` int64: beam ``b``'s points are ``nx[n_starts[b]:n_starts[b + 1]]``;
            every beam has at least one point (`beams` leaves out beams with none).
    """

    lx: np.ndarray
    ly: np.ndarray
    table: np.ndarray
    n_lidar: int
    n_semantic: int
    n_detections: int
    lidar_range_max_m: float
    semantic_range_max_m: float
    nx: np.ndarray = field(default_factory=lambda: _EMPTY_F)
    ny: np.ndarray = field(default_factory=lambda: _EMPTY_F)
    n_starts: np.ndarray = field(default_factory=lambda: _ZERO_START)

    def __post_init__(self) -> None:
        # read-only views: models cache what they derive from a BeamSet (`LikelihoodFieldModel._prepared`)
        for name in ("lx", "ly", "table", "nx", "ny", "n_starts"):
            v = np.asarray(getattr(self, name)).view()
            v.setflags(write=False)
            object.__setattr__(self, name, v)

    @property
    def n_negative(self) -> int:
        """Negative-evidence beams (unlabelled semantic returns sampled for missing objects)."""
        return int(self.n_starts.size - 1)


@numba.njit(cache=True, nogil=True, inline="always")
def _beam_cells(pu, pv, c, s, lu, lv, offset, outside, w, h, idx):  # pragma: no cover - compiled
    """Flat table index of every beam end point of one particle (exact IEEE arithmetic, no fastmath)."""
    for j in range(lu.shape[0]):
        fx = pu + (c * lu[j] - s * lv[j])
        fy = pv + (s * lu[j] + c * lv[j])
        if fx >= 0.0 and fx < w and fy >= 0.0 and fy < h:
            idx[j] = offset[j] + int(fy) * w + int(fx)
        else:
            idx[j] = outside[j]


@numba.njit(cache=True, nogil=True, inline="always")
def _gather_sum(flat, idx, lo, hi, acc):  # pragma: no cover - compiled
    """``sum(flat[idx[lo:hi]])`` in one fixed order, exact IEEE arithmetic (no fastmath).

    The order is the one LLVM chose for a fastmath loop on x86-64 (4 lanes x 4 accumulators,
    a 4-lane epilogue, then one by one), written out so that every compilation gives the same
    bits: under fastmath a freshly compiled kernel and the same kernel loaded from numba's cache
    summed in different orders, so the first process on a machine differed in the last bits from
    later ones. The sixteen partial sums live in ``acc`` (scratch, 16 floats) so that LLVM can
    keep them in vector registers without reassociating anything: no slower than fastmath was.
    """
    n = hi - lo
    m = lo + (n // 16) * 16
    r = 0.0
    if m > lo:
        for k in range(16):
            acc[k] = 0.0
        for j in range(lo, m, 16):
            for k in range(16):
                acc[k] += flat[idx[j + k]]
        r = ((acc[0] + acc[4]) + (acc[8] + acc[12]) + ((acc[2] + acc[6]) + (acc[10] + acc[14]))) + (
            ((acc[1] + acc[5]) + (acc[9] + acc[13])) + ((acc[3] + acc[7]) + (acc[11] + acc[15]))
        )
    e = m + ((hi - m) // 4) * 4
    if e > m:
        b0 = r
        b1 = b2 = b3 = 0.0
        for j in range(m, e, 4):
            b0 += flat[idx[j]]
            b1 += flat[idx[j + 1]]
            b2 += flat[idx[j + 2]]
            b3 += flat[idx[j + 3]]
        r = (b0 + b2) + (b1 + b3)
    for j in range(e, hi):
        r += flat[idx[j]]
    return r


@numba.njit(cache=True, nogil=True)
def log_likelihood_kernel(
    x, y, cos_t, sin_t, lu, lv, offset, outside, n_lidar, flat, ox, oy, inv_res, w, h, out_l, out_s
):  # pragma: no cover - compiled
    """Sum of per-beam ``log p`` for every particle (numba, single thread).

    For particle ``i`` and beam ``j`` the end point in cell units is
    ``(u, v) = ((x - ox) * inv_res + c*lu - s*lv, (y - oy) * inv_res + s*lu + c*lv)`` with the
    beam's robot-frame end point ``(lu, lv)`` already in cells; its cell is ``(floor(v), floor(u))``
    and its value ``flat[offset[j] + row * w + col]``, or ``flat[outside[j]]`` (the field's floor)
    off the ``h x w`` map. Beams ``j < n_lidar`` add to ``out_l[i]``, the others to ``out_s[i]``.

    Two phases per particle: the cell indices in exact arithmetic (so every end point lands in
    the same cell as in `filters.localization.likelihood_reference`), then a gather-sum in a
    fixed order (`_gather_sum`; the only difference from the reference is the order of the
    additions, ~1e-13).
    ``cos_t``/``sin_t`` are passed in so kernel and reference share them bit for bit.
    """
    nb = lu.shape[0]
    idx = np.empty(nb, np.int64)
    acc = np.empty(16)
    for i in range(x.shape[0]):
        _beam_cells(
            (x[i] - ox) * inv_res, (y[i] - oy) * inv_res, cos_t[i], sin_t[i], lu, lv, offset, outside, w, h, idx
        )
        out_l[i] = _gather_sum(flat, idx, 0, n_lidar, acc)
        out_s[i] = _gather_sum(flat, idx, n_lidar, nb, acc)


@numba.njit(cache=True, nogil=True, inline="always")
def _negative_cells(pu, pv, c, s, nu, nv, w, h, idx):  # pragma: no cover - compiled
    """`_beam_cells` for negative-evidence points: the same cells (``w * h`` off the map), the indices unsigned
    (no wrap-around check in the look-ups). A twin on purpose: `_beam_cells` with zero offsets and unsigned indices
    made `negative_evidence_kernel` 9-10 % slower on a v19 episode's calls; the tests against the former kernel,
    which used `_beam_cells`, hold the two to the same cells."""
    off = w * h
    for j in range(nu.shape[0]):
        fx = pu + (c * nu[j] - s * nv[j])
        fy = pv + (s * nu[j] + c * nv[j])
        if fx >= 0.0 and fx < w and fy >= 0.0 and fy < h:
            idx[j] = int(fy) * w + int(fx)
        else:
            idx[j] = off


@numba.njit(cache=True, nogil=True, inline="always")
def _negative_sum(codes, values, idx, starts):  # pragma: no cover - compiled
    """Sum over beams ``b`` of the lowest ``values[codes[idx[j]]]`` of its points ``starts[b] <= j < starts[b + 1]``
    (at most 0 each), beams in order.

    A beam's points go to two running minima (even and odd positions), which then meet: the same bits as
    one running minimum ``low = min(low, v)`` from ``low = 0.0``. ``min(a, v)`` is ``v if v < a else a``,
    so a minimum starting at +0.0 never becomes -0.0 (``-0.0 < 0.0`` is false) nor NaN: it is +0.0 or
    the lowest negative value seen, whatever the order. (Hence also ``acc`` is +0.0 or negative, never
    -0.0.) Two chains of ``min`` in flight instead of one."""
    acc = 0.0
    for b in range(starts.shape[0] - 1):
        lo0 = 0.0
        lo1 = 0.0
        j = starts[b]
        e = starts[b + 1]
        while j + 1 < e:
            lo0 = min(lo0, values[codes[idx[j]]])
            lo1 = min(lo1, values[codes[idx[j + 1]]])
            j += 2
        if j < e:
            lo0 = min(lo0, values[codes[idx[j]]])
        acc += min(lo0, lo1)
    return acc


@numba.njit(cache=True, nogil=True)
def negative_evidence_kernel(
    x, y, cos_t, sin_t, nu, nv, starts, codes, values, ox, oy, inv_res, w, h, out
):  # pragma: no cover - compiled
    """Add each particle's negative evidence to ``out`` (see `NegativeEvidenceConfig`).

    Beam ``b``'s points (robot frame, cells) are ``nu/nv[starts[b]:starts[b + 1]]``; a point's
    cell is found as in `log_likelihood_kernel` and its value is ``table[row * w + col]``, or
    ``table[w * h]`` (0: no object) off the ``h x w`` map, where ``table`` is
    `LikelihoodFieldModel.negative_table` given as ``values[codes]`` (`negative_codes`: a table of
    a few hundred distinct values in 2 bytes a cell, not 8, so that the random look-ups mostly hit
    the cache). A beam contributes the lowest value of its points (at most 0); beams are summed in
    order. As in `log_likelihood_kernel`, the cell indices of a particle's points come first, then
    the look-ups.
    """
    idx = np.empty(nu.shape[0], np.uint64)
    for i in range(x.shape[0]):
        pu, pv = (x[i] - ox) * inv_res, (y[i] - oy) * inv_res
        _negative_cells(pu, pv, cos_t[i], sin_t[i], nu, nv, w, h, idx)
        out[i] += _negative_sum(codes, values, idx, starts)


@numba.njit(cache=True, nogil=True, inline="always")
def step_back(x, y, th, c, s, dx, dy, dth):  # pragma: no cover - compiled
    """The pose ``(x, y, th)`` (``c``, ``s``: cos and sin of ``th``) moved by the robot-frame step ``(dx, dy, dth)``:
    `filters.pose.compose` of one pose, with the same operations (so the same bits); the heading wrapped as
    `filters.pose.wrap_angle`, the modulo skipped where it would return its argument."""
    yy = (th + dth) + np.pi
    return (
        x + c * dx - s * dy,
        y + s * dx + c * dy,
        yy - np.pi if 0.0 < yy < 2.0 * np.pi else yy % (2.0 * np.pi) - np.pi,
    )


@numba.njit(cache=True, nogil=True)
def window_kernel(
    p,
    flat,
    lu,
    lv,
    offset,
    outside,
    b_starts,
    n_lidar,
    nu,
    nv,
    p_starts,
    neg_starts,
    s_starts,
    codes,
    values,
    steps,
    ox,
    oy,
    inv_res,
    w,
    h,
    scale,
    total,
):  # pragma: no cover - compiled
    """A whole window log-likelihood (`filters.localization.audit.window_log_likelihood`) of the poses ``p``
    ``(M, 3)`` in one call, added to ``total`` ``(M,)``: entry after entry, newest first, ``scale * (lidar_ll +
    semantic_ll)`` as `log_likelihood_kernel` then `negative_evidence_kernel` compute them for the entry's beams
    (an entry with neither beams nor negative-evidence points adds nothing), each pose carried back along
    ``steps[e]`` ``(E - 1, 3)`` between entries (`step_back`); its cos and sin are taken here (the C library's, as
    `filters.pose.cos_sin`'s). The same bits as scoring entry by entry with
    `LikelihoodFieldModel.beam_log_likelihoods` and composing with `compose`.

    Entry ``e``'s beams are ``[b_starts[e], b_starts[e + 1])`` of ``lu, lv, offset, outside`` (its first
    ``n_lidar[e]`` lidar); its negative-evidence points ``[p_starts[e], p_starts[e + 1])`` of ``nu, nv``, beam by
    beam as ``neg_starts[s_starts[e]:s_starts[e + 1]]`` says (starts counted from the entry's first point; a
    single start: none)."""
    n_e = n_lidar.shape[0]
    most_b = 1
    most_p = 1
    for e in range(n_e):
        most_b = max(most_b, b_starts[e + 1] - b_starts[e])
        most_p = max(most_p, p_starts[e + 1] - p_starts[e])
    idx = np.empty(most_b, np.int64)
    acc = np.empty(16)
    n_idx = np.empty(most_p, np.uint64)
    for i in range(p.shape[0]):
        x = p[i, 0]
        y = p[i, 1]
        th = p[i, 2]
        t = total[i]
        for e in range(n_e):
            c = math.cos(th)
            s = math.sin(th)
            b0 = b_starts[e]
            nb = b_starts[e + 1] - b0
            q0 = s_starts[e]
            q1 = s_starts[e + 1]
            if nb or q1 - q0 > 1:
                pu, pv = (x - ox) * inv_res, (y - oy) * inv_res
                ll_l = 0.0
                ll_s = 0.0
                if nb:
                    b1 = b0 + nb
                    _beam_cells(pu, pv, c, s, lu[b0:b1], lv[b0:b1], offset[b0:b1], outside[b0:b1], w, h, idx)
                    ll_l = _gather_sum(flat, idx, 0, n_lidar[e], acc)
                    ll_s = _gather_sum(flat, idx, n_lidar[e], nb, acc)
                if q1 - q0 > 1:
                    k0 = p_starts[e]
                    k1 = p_starts[e + 1]
                    _negative_cells(pu, pv, c, s, nu[k0:k1], nv[k0:k1], w, h, n_idx)
                    ll_s += _negative_sum(codes, values, n_idx, neg_starts[q0:q1])
                t += scale * (ll_l + ll_s)
            if e + 1 < n_e:
                x, y, th = step_back(x, y, th, c, s, steps[e, 0], steps[e, 1], steps[e, 2])
        total[i] = t


@dataclass(frozen=True, eq=False)
class PackedWindow:
    """A window's entries (newest first) as `window_kernel` reads them (`LikelihoodFieldModel.packed_window`): the
    model's beams of every entry in one array each, and the steps back between entries. Read-only; ``model`` is the
    model that made it, the only one that may score it."""

    model: object
    flat: np.ndarray
    lu: np.ndarray
    lv: np.ndarray
    offset: np.ndarray
    outside: np.ndarray
    b_starts: np.ndarray
    n_lidar: np.ndarray
    nu: np.ndarray
    nv: np.ndarray
    p_starts: np.ndarray
    neg_starts: np.ndarray
    s_starts: np.ndarray
    codes: np.ndarray
    values: np.ndarray
    steps: np.ndarray


def _described(a) -> str:
    """``a``'s type, or for an array its shape, dtype and whether it is writable (for error messages)."""
    if isinstance(a, np.ndarray):
        return f"shape {a.shape}, {a.dtype}, {'writable' if a.flags.writeable else 'read-only'}"
    return type(a).__name__


def _checked_poses(poses: np.ndarray) -> np.ndarray:
    """``poses`` as a contiguous float64 ``(N, 3)`` array; ValueError if the shape is wrong or a value is
    not finite."""
    p = np.ascontiguousarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("poses contain NaN or inf")
    return p


class LikelihoodFieldModel:
    """Measurement model ``log p(lidar, semantic | pose, map)`` over an ``(N, 3)`` pose array.

    Model only, no filter state (``nchopin/particles`` style): the filter calls
    `log_likelihood` and owns the weights.

    Args:
        grid: the map; its occupied mask gives the lidar field, ``class_mask(k)`` the
            field of class ``k`` (scan label ``k + 1``).
        lidar: parameters of the lidar field.
        semantic: parameters of the semantic fields (shared by all classes).
        negative: evidence from objects not seen (`NegativeEvidenceConfig`); None = off.
        backend: ``"numba"`` (the fast kernel) or ``"numpy"`` (the reference in
            `filters.localization.likelihood_reference`; same numbers, slower).
    """

    def __init__(
        self,
        grid: GridMap,
        lidar: LikelihoodFieldConfig | None = None,
        semantic: LikelihoodFieldConfig | None = None,
        backend: str = "numba",
        negative: NegativeEvidenceConfig | None = None,
    ) -> None:
        if not isinstance(grid, GridMap):
            raise TypeError(f"grid must be a filters.mapping.grid.GridMap, got {type(grid).__name__}")
        if backend not in ("numba", "numpy"):
            raise ValueError(f"backend must be 'numba' or 'numpy', got {backend!r}")
        self.grid = grid
        self.lidar_config = lidar if lidar is not None else LikelihoodFieldConfig()
        self.semantic_config = semantic if semantic is not None else DEFAULT_SEMANTIC_FIELD
        self.negative_config = _negative_in_effect(negative)
        self.backend = backend
        res = grid.resolution_m
        n_cls = len(grid.class_names)
        fields = np.empty((1 + n_cls,) + grid.shape, dtype=np.float64)
        fields[0] = distance_field(grid.occupied_mask(), res)
        for k in range(n_cls):
            fields[1 + k] = distance_field(grid.class_mask(k), res)
        fields.setflags(write=False)
        self.distance_fields_m = fields
        """``(1 + C, H, W)`` uncapped distances in metres: ``[0]`` to occupied cells, ``[k + 1]`` to class ``k``."""
        self._tables: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._negative_table: np.ndarray | None = None
        self._negative_codes: tuple[np.ndarray, np.ndarray] | None = None
        self._kernel_beams: weakref.WeakKeyDictionary[BeamSet, tuple] = weakref.WeakKeyDictionary()

    def reconfigured(
        self,
        lidar: LikelihoodFieldConfig,
        semantic: LikelihoodFieldConfig,
        negative: NegativeEvidenceConfig | None = None,
    ) -> LikelihoodFieldModel:
        """A model of the same map and backend with other field parameters, sharing this model's distance
        fields (a few ms per class on a lab-size map, not computed again); the same numbers as
        ``LikelihoodFieldModel(self.grid, lidar, semantic, self.backend, negative)``."""
        for name, cfg in (("lidar", lidar), ("semantic", semantic)):
            if not isinstance(cfg, LikelihoodFieldConfig):
                raise TypeError(f"{name} must be a LikelihoodFieldConfig, got {type(cfg).__name__}")
        new = copy.copy(self)
        new.lidar_config, new.semantic_config = lidar, semantic
        new.negative_config = _negative_in_effect(negative)
        new._tables, new._negative_table, new._negative_codes = {}, None, None
        new._kernel_beams = weakref.WeakKeyDictionary()
        return new

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        del state["_kernel_beams"]  # a cache of weak references: not picklable, rebuilt on use
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._kernel_beams = weakref.WeakKeyDictionary()

    @functools.cached_property
    def object_distance_m(self) -> np.ndarray:
        """``(H, W)`` distance (metres) to the nearest cell of any class (``inf`` if the map has none),
        read-only; computed once (the NumPy reference reads it at every call)."""
        f = self.distance_fields_m
        d = f[1:].min(axis=0) if f.shape[0] > 1 else np.full(f.shape[1:], np.inf)
        d.setflags(write=False)
        return d

    def negative_table(self) -> np.ndarray:
        """``(H * W + 1,)`` ``log(1 - p_detect * presence)`` per cell (`NegativeEvidenceConfig.log_q`),
        then 0 (the value off the map), read-only."""
        if self._negative_table is None:
            t = np.concatenate([self.negative_config.log_q(self.object_distance_m).ravel(), [0.0]])
            t.setflags(write=False)
            self._negative_table = t
        return self._negative_table

    def negative_codes(self) -> tuple[np.ndarray, np.ndarray]:
        """`negative_table` as ``(codes, values)``, ``values[codes]`` its exact bytes (``-0.0`` kept apart
        from ``0.0``): ``values`` its distinct values (a few hundred), ``codes`` ``uint16`` (``uint32`` past
        65536 values), read-only. What the compiled kernels read: a quarter of the table's bytes."""
        if self._negative_codes is None:
            self._negative_codes = table_codes(self.negative_table())
        return self._negative_codes

    @property
    def n_classes(self) -> int:
        return len(self.grid.class_names)

    def config_of(self, t: int) -> LikelihoodFieldConfig:
        """Config of field ``t`` (0 = lidar, ``k + 1`` = class ``k``)."""
        return self.lidar_config if t == 0 else self.semantic_config

    def log_tables(self, lidar_range_max_m: float, semantic_range_max_m: float) -> tuple[np.ndarray, np.ndarray]:
        """``(tables (1+C, H, W), floors (1+C,))`` of ``log p`` per cell, cached per range pair."""
        tables, floors, _ = self._log_tables(lidar_range_max_m, semantic_range_max_m)
        return tables, floors

    def _log_tables(self, lidar_range_max_m: float, semantic_range_max_m: float):
        """``(tables, floors, flat)``: ``flat`` = ``tables.ravel()`` followed by ``floors`` (the kernel's input)."""
        key = (float(lidar_range_max_m), float(semantic_range_max_m))
        hit = self._tables.get(key)
        if hit is not None:
            return hit
        n_t = self.distance_fields_m.shape[0]
        tables = np.empty(self.distance_fields_m.shape, dtype=np.float64)
        floors = np.empty(n_t, dtype=np.float64)
        for t in range(n_t):
            cfg = self.config_of(t)
            rmax = key[0] if t == 0 else key[1]
            floors[t] = cfg.log_p(np.array(cfg.max_dist_m), rmax)
            # log_p caps distances at max_dist_m, so every farther cell holds the floor: compute the near ones only
            d = self.distance_fields_m[t]
            near = d < cfg.max_dist_m
            tables[t] = floors[t]
            tables[t][near] = cfg.log_p(d[near], rmax)
        if len(self._tables) >= 4:
            self._tables.pop(next(iter(self._tables)))
        flat = np.concatenate([tables.ravel(), floors])
        for a in (tables, floors, flat):
            a.setflags(write=False)
        self._tables[key] = (tables, floors, flat)
        return self._tables[key]

    def check_labels(self, semantic: SemanticScan) -> None:
        """ValueError if a label of ``semantic`` has no class in the map (labels ``1..n_classes``).

        `filters.localization.mcl.MonteCarloLocalizer.update` calls it before its motion gate, so a
        bad scan is refused whether or not the update runs."""
        if semantic.labels.size and semantic.labels.max() > self.n_classes:
            raise ValueError(
                f"semantic label {int(semantic.labels.max())} has no class in the map "
                f"(labels 1..{self.n_classes} = {self.grid.class_names})"
            )

    def beams(self, lidar: LaserScan | None, semantic: SemanticScan | None) -> BeamSet:
        """Select the beams of one update and turn them into robot-frame end points (the numba backend in one
        compiled pass, `filters.localization.beam_kernels.beam_parts`; the numpy backend by `beams_reference`: the
        same arrays, bit for bit).

        Raises:
            ValueError: a semantic label has no class in the map, or, with negative evidence, a semantic
                return lies farther than ``filters.numbers.MAX_LENGTH_M``.
            TypeError: the scans are not `LaserScan` / `SemanticScan`.
        """
        if self.backend == "numpy":
            return self.beams_reference(lidar, semantic)
        self._check_scans(lidar, semantic)
        if lidar is not None:
            c = self.lidar_config
            lid = (lidar.ranges, lidar.angles, float(lidar.range_min_m), float(lidar.range_max_m), lidar.sensor_pose)
            lid += (int(c.beam_stride), int(c.max_beams))
        else:
            lid = (_EMPTY_F, _EMPTY_F, 0.0, 1.0, _ZERO_POSE, 1, 0)
        if semantic is not None:
            c = self.semantic_config
            neg = self.negative_config
            sem = (semantic.ranges, semantic.angles, semantic.labels, float(semantic.range_max_m), semantic.sensor_pose)
            sem += (int(c.beam_stride), int(c.max_beams), int(neg.max_beams) if neg.enabled else 0)
            sem += (float(neg.margin_m), float(neg.step_m))
        else:
            sem = (_EMPTY_F, _EMPTY_F, _EMPTY_I, 1.0, _ZERO_POSE, 1, 0, 0, 0.0, 1.0)
        lx, ly, table, n_l, n_s, n_det, nx, ny, n_starts = beam_parts(*lid, *sem)
        return BeamSet(
            lx=lx,
            ly=ly,
            table=table,
            n_lidar=int(n_l),
            n_semantic=int(n_s),
            n_detections=int(n_det),
            lidar_range_max_m=float(lidar.range_max_m) if lidar is not None else 1.0,
            semantic_range_max_m=float(semantic.range_max_m) if semantic is not None else 1.0,
            nx=nx,
            ny=ny,
            n_starts=n_starts,
        )

    def _check_scans(self, lidar: LaserScan | None, semantic: SemanticScan | None) -> None:
        """`beams`' argument checks (see its Raises)."""
        if lidar is not None and not isinstance(lidar, LaserScan):
            raise TypeError(f"lidar must be a LaserScan, got {type(lidar).__name__}")
        if semantic is None:
            return
        if not isinstance(semantic, SemanticScan):
            raise TypeError(f"semantic must be a SemanticScan, got {type(semantic).__name__}")
        self.check_labels(semantic)
        r = semantic.ranges
        if self.negative_config.enabled and r.size and r.max() > MAX_LENGTH_M:
            far = r[(r > MAX_LENGTH_M) & (r < semantic.range_max_m)]
            if far.size:  # a point every step_m along such a return: more than memory holds
                raise ValueError(
                    f"semantic return at {far[0]:.3g} m: negative evidence samples points along each return, which "
                    f"takes returns up to {MAX_LENGTH_M:g} m (filters.numbers.MAX_LENGTH_M); not metres?"
                )

    def beams_reference(self, lidar: LaserScan | None, semantic: SemanticScan | None) -> BeamSet:
        """`beams` as NumPy array code (the specification the compiled pass is tested against; the numpy
        backend's)."""
        self._check_scans(lidar, semantic)
        lxs, lys, tabs = [], [], []
        nx, ny, n_starts = _EMPTY_F, _EMPTY_F, _ZERO_START
        n_l = n_s = n_det = 0
        l_rmax = s_rmax = 1.0
        if lidar is not None:
            c = self.lidar_config
            idx = select_beams(lidar.valid, c.beam_stride, c.max_beams)
            ex, ey = beam_endpoints(lidar.ranges[idx], lidar.angles[idx], lidar.sensor_pose)
            lxs.append(ex)
            lys.append(ey)
            tabs.append(np.zeros(idx.size, np.int64))
            n_l = int(idx.size)
            l_rmax = lidar.range_max_m
        if semantic is not None:
            c = self.semantic_config
            idx = select_beams(semantic.labelled, c.beam_stride, c.max_beams)
            ex, ey = beam_endpoints(semantic.ranges[idx], semantic.angles[idx], semantic.sensor_pose)
            lxs.append(ex)
            lys.append(ey)
            tabs.append(semantic.labels[idx].astype(np.int64))
            n_s = int(idx.size)
            n_det = count_detections(semantic)
            s_rmax = semantic.range_max_m
            neg = self.negative_config
            if neg.enabled:
                nidx = negative_beams(semantic.labels, semantic.ranges, s_rmax, neg.max_beams)
                counts, r = neg.sample_ranges(semantic.ranges[nidx])
                keep = counts > 0
                if keep.any():
                    nx, ny = beam_endpoints(r, np.repeat(semantic.angles[nidx], counts), semantic.sensor_pose)
                    n_starts = np.concatenate([[0], np.cumsum(counts[keep])]).astype(np.int64)
        cat = (lambda parts, dt: np.concatenate(parts).astype(dt)) if lxs else (lambda parts, dt: np.zeros(0, dt))
        return BeamSet(
            lx=cat(lxs, np.float64),
            ly=cat(lys, np.float64),
            table=cat(tabs, np.int64),
            n_lidar=n_l,
            n_semantic=n_s,
            n_detections=n_det,
            lidar_range_max_m=float(l_rmax),
            semantic_range_max_m=float(s_rmax),
            nx=nx,
            ny=ny,
            n_starts=n_starts,
        )

    def log_likelihood_terms(
        self, poses: np.ndarray, lidar: LaserScan | None, semantic: SemanticScan | None = None
    ) -> tuple[np.ndarray, np.ndarray, BeamSet]:
        """``(lidar_ll (N,), semantic_ll (N,), beams)``: the two log factors of paper 004 Eq. 8.

        Args:
            poses: ``(N, 3)`` poses ``(x m, y m, theta rad)``, finite.
            lidar: lidar scan or None (then ``lidar_ll`` is 0).
            semantic: semantic scan or None (then ``semantic_ll`` is 0).
        """
        p = _checked_poses(poses)
        beams = self.beams(lidar, semantic)
        ll_l, ll_s = self._scored(p, beams)
        return ll_l, ll_s, beams

    def beam_log_likelihoods(
        self, poses: np.ndarray, beams: BeamSet, trig: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(lidar_ll (N,), semantic_ll (N,))`` of the beams of `beams` (a `BeamSet` this model made) for
        ``poses`` ``(N, 3)``: `log_likelihood_terms` without selecting the beams again (for callers that
        score the same scans more than once, such as the convergence audit).

        ``trig``: ``(np.cos(p[:, 2]), np.sin(p[:, 2]))`` of the checked poses ``p`` if the caller has
        them (the convergence audit needs them to compose poses too); None: computed here.

        Raises:
            ValueError: ``trig`` is not two float64 arrays of shape ``(N,)``."""
        p = _checked_poses(poses)
        if trig is not None:
            c, s = trig
            n = (p.shape[0],)
            for a in (c, s):
                if not (isinstance(a, np.ndarray) and a.shape == n and a.dtype == np.float64):
                    raise ValueError(f"trig must be (cos, sin) of the poses' headings: two float64 arrays of shape {n}")
        return self._scored(p, beams, trig)

    def packed_window(self, beams: list[BeamSet], steps: list[np.ndarray]) -> PackedWindow | None:
        """The kernel inputs of a window whose entries, newest first, have the `BeamSet` s ``beams`` (this model's)
        and the steps back ``steps`` (`filters.localization.audit.back_steps`: ``len(beams) - 1`` robot-frame
        ``(3,)`` steps, the first taking a pose at the newest entry to the one before), for `score_window`; None
        if `window_kernel` cannot score it in one call (the numpy backend, no entry, fewer steps than that, or
        entries whose scans' range limits differ and so read different tables)."""
        n = len(beams)
        if self.backend != "numba" or n == 0 or len(steps) < n - 1:
            return None
        prepared = [self._prepared(b) for b in beams]
        flat = self._shared_tables(beams, prepared)
        if flat is None:
            return None
        negative = [self._weighs_negative(b) for b in beams]
        b_starts = np.cumsum([0] + [b.lx.size for b in beams])
        p_starts = np.cumsum([0] + [b.nx.size if neg else 0 for b, neg in zip(beams, negative)])
        starts = [b.n_starts if neg else _ZERO_START for b, neg in zip(beams, negative)]
        codes, values = self.negative_codes() if any(negative) else (_NO_CODES, _NO_VALUES)
        packed = PackedWindow(
            model=self,
            flat=flat,
            lu=np.concatenate([prep[1] for prep in prepared]),
            lv=np.concatenate([prep[2] for prep in prepared]),
            offset=np.concatenate([prep[3] for prep in prepared]),
            outside=np.concatenate([prep[4] for prep in prepared]),
            b_starts=b_starts,
            n_lidar=np.array([b.n_lidar for b in beams], dtype=np.int64),
            nu=np.concatenate([prep[5] for prep, neg in zip(prepared, negative) if neg] or [_EMPTY_F]),
            nv=np.concatenate([prep[6] for prep, neg in zip(prepared, negative) if neg] or [_EMPTY_F]),
            p_starts=p_starts,
            neg_starts=np.concatenate(starts),
            s_starts=np.cumsum([0] + [a.size for a in starts]),
            codes=codes,
            values=values,
            steps=np.array([np.asarray(d, dtype=np.float64).reshape(3) for d in steps[: n - 1]]).reshape(n - 1, 3),
        )
        built = ("lu", "lv", "offset", "outside", "b_starts", "n_lidar", "nu", "nv", "p_starts", "neg_starts")
        for name in (*built, "s_starts", "steps"):
            getattr(packed, name).setflags(write=False)
        return packed

    def _shared_tables(self, beams: list[BeamSet], prepared: list[tuple]) -> np.ndarray | None:
        """The kernels' ``flat`` tables every one of ``beams`` (``prepared``: their `_prepared` inputs) reads its
        values from, or None if there are none.

        A `BeamSet`'s tables are those of its scans' range limits (`_log_tables`); the lidar table depends on the
        lidar's limit only, the class tables on the camera's. An entry without a lidar scan (a turn-in-place update)
        or without a camera scan carries a placeholder limit for it, and an entry without lidar (or labelled) beams
        reads no lidar (or class) table: for the beams they have they read the same values from the tables of the
        other entries' limits. Those tables are taken from an
        entry whose own limits they are (never built here). None where two entries with lidar (or labelled) beams
        differ in their limit, or no entry has the limits the others need."""
        lidar = {b.lidar_range_max_m for b in beams if b.n_lidar}
        semantic = {b.semantic_range_max_m for b in beams if b.lx.size > b.n_lidar}
        if len(lidar) > 1 or len(semantic) > 1:
            return None
        for b, prep in zip(beams, prepared):
            if (not lidar or b.lidar_range_max_m in lidar) and (not semantic or b.semantic_range_max_m in semantic):
                return prep[0]
        return None

    def score_window(self, packed: PackedWindow, p: np.ndarray, scale: float, total: np.ndarray) -> None:
        """Add ``scale`` times the window log-likelihood of ``packed`` (`packed_window`, of this model) for the
        checked poses ``p`` ``(M, 3)`` (contiguous float64, finite) to ``total`` ``(M,)``, in one compiled call
        (`window_kernel`).

        Raises:
            ValueError: ``packed`` is another model's, ``p`` is not a C-contiguous float64 ``(M, 3)`` array, or
                ``total`` not a writable float64 ``(M,)`` one."""
        if not isinstance(packed, PackedWindow) or packed.model is not self:
            raise ValueError("packed must be a PackedWindow this model made (packed_window), got another's or none")
        if not (isinstance(p, np.ndarray) and p.dtype == np.float64 and p.ndim == 2 and p.shape[1] == 3):
            raise ValueError(f"p must be a float64 (M, 3) array, got {_described(p)}")
        if not p.flags.c_contiguous:
            raise ValueError("p must be C-contiguous")
        ok = isinstance(total, np.ndarray) and total.dtype == np.float64 and total.shape == (p.shape[0],)
        if not (ok and total.flags.writeable):
            raise ValueError(f"total must be a writable float64 ({p.shape[0]},) array, got {_described(total)}")
        if p.shape[0]:
            ox, oy = self.grid.origin_xy_m
            h, w = self.grid.shape
            window_kernel(
                p, packed.flat, packed.lu, packed.lv, packed.offset, packed.outside, packed.b_starts,
                packed.n_lidar, packed.nu, packed.nv, packed.p_starts, packed.neg_starts, packed.s_starts,
                packed.codes, packed.values, packed.steps, float(ox), float(oy), 1.0 / self.grid.resolution_m, w, h,
                float(scale), total,
            )  # fmt: skip

    def _weighs_negative(self, beams: BeamSet) -> bool:
        """Whether `beams` has negative-evidence points this model weighs. A model without negative evidence
        (the audit's blurred screen model, scoring the filter's beams) skips them: its table is all 0, so
        adding them changed nothing."""
        return bool(beams.n_negative) and self.negative_config.enabled

    def _prepared(self, beams: BeamSet) -> tuple:
        """The kernels' inputs that depend on the beams only, computed once per `BeamSet` (its arrays
        are never written): ``(flat, lu, lv, offset, outside, nu, nv)``."""
        prep = self._kernel_beams.get(beams)
        if prep is None:
            _, _, flat = self._log_tables(beams.lidar_range_max_m, beams.semantic_range_max_m)
            h, w = self.grid.shape
            inv_res = 1.0 / self.grid.resolution_m
            prep = (
                flat,
                beams.lx * inv_res,
                beams.ly * inv_res,
                beams.table * (h * w),
                beams.table + self.distance_fields_m.size,
                beams.nx * inv_res,
                beams.ny * inv_res,
            )
            self._kernel_beams[beams] = prep
        return prep

    def _scored(
        self, p: np.ndarray, beams: BeamSet, trig: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The two log factors for checked, contiguous float64 poses ``p`` (``trig``: as `beam_log_likelihoods`)."""
        if self.backend == "numpy":
            return log_likelihood_terms_reference(self, p, beams)
        n = p.shape[0]
        out_l = np.zeros(n)
        out_s = np.zeros(n)
        negative = self._weighs_negative(beams)
        if n and (beams.lx.size or negative):
            flat, lu, lv, offset, outside, nu, nv = self._prepared(beams)
            ox, oy = self.grid.origin_xy_m
            h, w = self.grid.shape
            inv_res = 1.0 / self.grid.resolution_m
            cos_t, sin_t = trig if trig is not None else cos_sin(p[:, 2])
            x, y = p[:, 0].copy(), p[:, 1].copy()
            if beams.lx.size:
                log_likelihood_kernel(
                    x, y, cos_t, sin_t, lu, lv, offset, outside, beams.n_lidar, flat,
                    float(ox), float(oy), inv_res, w, h, out_l, out_s,
                )  # fmt: skip
            if negative:
                negative_evidence_kernel(
                    x, y, cos_t, sin_t, nu, nv, beams.n_starts, *self.negative_codes(),
                    float(ox), float(oy), inv_res, w, h, out_s,
                )  # fmt: skip
        return out_l, out_s

    def log_likelihood(
        self, poses: np.ndarray, lidar: LaserScan | None, semantic: SemanticScan | None = None
    ) -> np.ndarray:
        """``(N,)`` ``log p(lidar | pose) + log p(semantic | pose)`` (natural log, unnormalised)."""
        ll_l, ll_s, _ = self.log_likelihood_terms(poses, lidar, semantic)
        return ll_l + ll_s


# ------------------------------------------------------------------------------------------ model cache
MODEL_CACHE_SIZE = 4
"""Likelihood-field models kept by `cached_model` (least recently used dropped first)."""

_models: OrderedDict[tuple, LikelihoodFieldModel] = OrderedDict()
_content_keys: weakref.WeakKeyDictionary[GridMap, str] = weakref.WeakKeyDictionary()


def grid_content_key(grid: GridMap) -> str:
    """Hex digest of everything in ``grid`` a likelihood field depends on (grids, raster, classes, thresholds).

    Computed once per GridMap object (its arrays are read-only), then remembered.
    """
    key = _content_keys.get(grid)
    if key is None:
        h = hashlib.blake2b(digest_size=16)
        meta = (grid.shape, grid.resolution_m, grid.origin_xy_m, grid.class_names)
        h.update(repr((meta, grid.occupied_thresh, grid.free_thresh, grid.semantic_thresh)).encode())
        h.update(np.ascontiguousarray(grid.occupancy).tobytes())
        h.update(np.ascontiguousarray(grid.semantic).tobytes())
        key = h.hexdigest()
        _content_keys[grid] = key
    return key


def cached_model(
    grid: GridMap,
    lidar: LikelihoodFieldConfig | None = None,
    semantic: LikelihoodFieldConfig | None = None,
    backend: str = "numba",
    negative: NegativeEvidenceConfig | None = None,
) -> LikelihoodFieldModel:
    """A `LikelihoodFieldModel` for ``(grid, lidar, semantic, backend, negative)``, built once per process.

    Keyed on the map's *content* (`grid_content_key`) and the configs, so two GridMap
    objects holding the same map share one model; at most `MODEL_CACHE_SIZE` models are
    kept. The model is stateless apart from its own caches, so sharing it between filters is safe.
    """
    if not isinstance(grid, GridMap):
        raise TypeError(f"grid must be a filters.mapping.grid.GridMap, got {type(grid).__name__}")
    lidar = lidar if lidar is not None else LikelihoodFieldConfig()
    semantic = semantic if semantic is not None else DEFAULT_SEMANTIC_FIELD
    negative = _negative_in_effect(negative)
    key = (grid_content_key(grid), lidar, semantic, backend, negative)
    model = _models.get(key)
    if model is None:
        model = LikelihoodFieldModel(grid, lidar, semantic, backend, negative)  # validates the arguments
        _models[key] = model
        while len(_models) > MODEL_CACHE_SIZE:
            _models.popitem(last=False)
    else:
        _models.move_to_end(key)
    return model
