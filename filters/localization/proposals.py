"""Sensor-based pose proposals: candidate robot poses drawn from the current scan.

Used by `filters.localization.mcl.MonteCarloLocalizer` to inject particles where
the sensors say the robot could be (sensor resetting, Lenser & Veloso 2000; Mixture MCL,
Thrun et al. 2001), instead of uniformly over free space:

* **From a semantic detection.** A detection is a maximal run of adjacent labelled beams
  with one label (`detection_runs`); its middle beam gives a range ``r`` and a bearing
  ``a`` in the sensor's frame, so the object lies at ``p = sensor_pose ⊕ (r cos a, r sin a)``
  in the robot frame (`filters.robot_data.scans.beam_endpoints`). A candidate takes a map
  cell ``c`` of the detected class at random, a heading ``theta`` uniform in ``[-pi, pi)``,
  and puts the robot at ``c - R(theta) p`` (with the sensor at the robot's centre, facing
  forward: ``c - r (cos(theta + a), sin(theta + a))``). A class with few instances in the map
  concentrates these candidates on a few rings around its objects.
* **Uniform.** Poses uniform over the map's free space.

Candidates that fall outside free space are replaced by uniform ones. The caller weights
the candidates with its own measurement model and draws the injected particles from them
(`ScanProposal.draw`).
"""

from __future__ import annotations

import numpy as np

from filters.localization.belief import heading_bins
from filters.mapping.grid import GridMap
from filters.pose import wrap_angle
from filters.robot_data.scans import SemanticScan, beam_endpoints
from filters.smc.resampling import normalise_weights


def detection_runs(semantic: SemanticScan) -> list[tuple[int, float, float]]:
    """``[(label, range m, bearing rad), ...]`` of each detection: the middle beam of every
    maximal run of adjacent labelled beams carrying the same label (range and bearing in the sensor's
    frame, ``semantic.sensor_pose``)."""
    lab = np.where(semantic.labelled, semantic.labels, 0)
    out = []
    i, n = 0, lab.size
    while i < n:
        if lab[i] == 0:
            i += 1
            continue
        j = i
        while j + 1 < n and lab[j + 1] == lab[i]:
            j += 1
        m = (i + j) // 2
        out.append((int(lab[i]), float(semantic.ranges[m]), float(semantic.angles[m])))
        i = j + 1
    return out


class ScanProposal:
    """Candidate poses from a scan, over one map.

    Args:
        grid: the filter's map; class ``k`` cells are ``grid.class_mask(k)``.
        sample_free: ``sample_free(n) -> (n, 3)`` uniform free poses (the filter's own sampler,
            which draws from the filter's generator).
        range_jitter_m: std of the Gaussian noise added to a detection's range.
    """

    def __init__(self, grid: GridMap, sample_free, range_jitter_m: float = 0.1) -> None:
        self.grid = grid
        self.sample_free = sample_free
        self.range_jitter_m = float(range_jitter_m)
        self._free = grid.free_mask()
        self._class_xy: dict[int, np.ndarray] = {}

    def class_cells(self, label: int) -> np.ndarray:
        """``(M, 2)`` centres of the map cells of label ``label`` (class ``label - 1``)."""
        if label not in self._class_xy:
            row, col = np.divmod(self.grid.class_cells(label - 1), self.grid.shape[1])
            self._class_xy[label] = self.grid.cell_centers(row, col)
        return self._class_xy[label]

    def candidates(self, n: int, semantic: SemanticScan | None, semantic_frac: float, rng) -> np.ndarray:
        """``(n, 3)`` candidates: about ``semantic_frac`` of them from the detections in
        ``semantic`` (shared equally between detections), the rest uniform over free space."""
        runs = [] if semantic is None else [d for d in detection_runs(semantic) if self.class_cells(d[0]).size]
        n_sem = int(round(n * semantic_frac)) if runs else 0
        parts = []
        if n_sem:
            which = rng.integers(0, len(runs), size=n_sem)
            out = np.empty((n_sem, 3))
            mounted = bool(np.any(np.asarray(semantic.sensor_pose) != 0.0))
            for k, (label, r, a) in enumerate(runs):
                sel = np.flatnonzero(which == k)
                cells = self.class_cells(label)
                c = cells[rng.integers(0, cells.shape[0], size=sel.size)]
                res = self.grid.resolution_m
                c = c + (rng.random((sel.size, 2)) - 0.5) * res
                th = -np.pi + 2.0 * np.pi * rng.random(sel.size)
                rr = r + self.range_jitter_m * rng.standard_normal(sel.size)
                if mounted:  # the object at p in the robot frame: the robot at c - R(theta) p
                    px, py = beam_endpoints(rr, np.full(sel.size, a), semantic.sensor_pose)
                    cos_t, sin_t = np.cos(th), np.sin(th)
                    out[sel, 0] = c[:, 0] - (cos_t * px - sin_t * py)
                    out[sel, 1] = c[:, 1] - (sin_t * px + cos_t * py)
                else:  # the same for a sensor at the robot's centre facing forward (kept: its rounding)
                    out[sel, 0] = c[:, 0] - rr * np.cos(th + a)
                    out[sel, 1] = c[:, 1] - rr * np.sin(th + a)
                out[sel, 2] = wrap_angle(th)
            row, col = self.grid.world_to_cell(out[:, :2])
            ok = self.grid.in_bounds(row, col)
            ok[ok] = self._free[row[ok], col[ok]]
            parts.append(out[ok])
        parts.append(self.sample_free(n - sum(p.shape[0] for p in parts)))
        return np.vstack(parts)

    def draw(self, m: int, candidates: np.ndarray, log_likelihood: np.ndarray, rng) -> np.ndarray:
        """``(m, 3)`` poses drawn from ``candidates`` in proportion to ``exp(log_likelihood)``
        (multinomial draws; non-finite values count as zero)."""
        ll = np.where(np.isfinite(log_likelihood), log_likelihood, -np.inf)
        if not np.isfinite(ll).any():
            return candidates[rng.integers(0, candidates.shape[0], size=m)]
        w = normalise_weights(np.exp(ll - ll.max()))
        return candidates[rng.choice(candidates.shape[0], size=m, p=w)]


_MAX_DENSE_CELLS = 1 << 22
"""`prior_mass_near` rasters the bins of a bounding box up to this many cells (32 MB of float64)."""


def prior_mass_near(
    prior: np.ndarray, weights: np.ndarray, query: np.ndarray, bin_xy_m: float, bin_theta_rad: float
) -> np.ndarray:
    """``(M,)`` weight of the ``prior`` particles in each ``query`` pose's bin and its 26 neighbours
    (each bin once: fewer with under 3 heading bins).

    Bins are ``bin_xy_m`` square in position and ``2 pi / round(2 pi / bin_theta_rad)`` wide in
    heading (which wraps). A coarse density of the prior belief at the query poses: Mixture MCL
    weighs its sensor-drawn ("dual") samples by it (Thrun et al. 2001).

    Args:
        prior: ``(N, 3)`` poses ``(x m, y m, theta rad)``; weights: ``(N,)`` their weights (>= 0).
        query: ``(M, 3)`` poses.
    """

    def cells(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        t, n_t = heading_bins(p[:, 2], bin_theta_rad)
        return np.floor(p[:, 0] / bin_xy_m).astype(np.int64), np.floor(p[:, 1] / bin_xy_m).astype(np.int64), t, n_t

    if prior.shape[0] == 0 or query.shape[0] == 0:
        return np.zeros(query.shape[0])
    px, py, pt, n_t = cells(prior)
    qx, qy, qt, _ = cells(query)
    x0 = min(int(px.min()), int(qx.min())) - 1
    y0 = min(int(py.min()), int(qy.min())) - 1
    ny = max(int(py.max()), int(qy.max())) - y0 + 2

    def key(x, y, t):
        return ((x - x0) * ny + (y - y0)) * n_t + t

    size = (max(int(px.max()), int(qx.max())) - x0 + 2) * ny * n_t
    dense = size <= _MAX_DENSE_CELLS  # a raster over the bounding box; else the occupied bins only
    if dense:
        mass = np.bincount(key(px, py, pt), weights=weights, minlength=size)
    else:
        uk, inv = np.unique(key(px, py, pt), return_inverse=True)
        mass = np.bincount(inv, weights=weights, minlength=uk.size)
    t_offsets = (-1, 0, 1) if n_t >= 3 else tuple(range(n_t))  # each neighbouring heading bin once
    d = np.array([(dx, dy, dt) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dt in t_offsets]).T
    k = key(qx[:, None] + d[0], qy[:, None] + d[1], (qt[:, None] + d[2]) % n_t)  # (M, 27)
    if dense:
        out = mass[k].sum(axis=1)
    else:
        i = np.minimum(np.searchsorted(uk, k), uk.size - 1)
        out = np.where(uk[i] == k, mass[i], 0.0).sum(axis=1)
    return out
