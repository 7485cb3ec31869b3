"""Sensor-based pose proposals: candidate robot poses drawn from the current scan.

Used by `filters.localization.mcl.MonteCarloLocalizer` to inject particles where
the sensors say the robot could be (sensor resetting, Lenser & Veloso 2000; Mixture MCL,
Thrun et al. 2001), instead of uniformly over free space:

* **From a semantic detection.** A detection is a maximal run of adjacent labelled beams
  with one label (`detection_runs`); its middle beam gives a range ``r`` and a bearing
  ``a`` in the robot frame. A candidate takes a map cell ``c`` of the detected class at
  random, a heading ``theta`` uniform in ``[-pi, pi)``, and puts the robot at
  ``c - r (cos(theta + a), sin(theta + a))``. A class with few instances in the map
  concentrates these candidates on a few rings around its objects.
* **Uniform.** Poses uniform over the map's free space.

Candidates that fall outside free space are replaced by uniform ones. The caller weights
the candidates with its own measurement model and draws the injected particles from them
(`ScanProposal.draw`).
"""

from __future__ import annotations

import numpy as np

from filters.mapping.grid import GridMap
from filters.pose import wrap_angle
from filters.robot_data.scans import SemanticScan
from filters.smc.resampling import normalise_weights


def detection_runs(semantic: SemanticScan) -> list[tuple[int, float, float]]:
    """``[(label, range m, bearing rad), ...]`` of each detection: the middle beam of every
    maximal run of adjacent labelled beams carrying the same label."""
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
            for k, (label, r, a) in enumerate(runs):
                sel = np.flatnonzero(which == k)
                cells = self.class_cells(label)
                c = cells[rng.integers(0, cells.shape[0], size=sel.size)]
                res = self.grid.resolution_m
                c = c + (rng.random((sel.size, 2)) - 0.5) * res
                th = -np.pi + 2.0 * np.pi * rng.random(sel.size)
                rr = r + self.range_jitter_m * rng.standard_normal(sel.size)
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
