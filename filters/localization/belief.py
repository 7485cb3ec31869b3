"""Belief summary of a weighted particle set: what a filter currently holds, in a few numbers.

:func:`summarize` turns ``(N, 3)`` poses and ``(N,)`` weights into a frozen
:class:`Belief` whose :meth:`Belief.as_dict` is plain Python (floats, ints,
lists), ready for a Gymnasium ``info`` dict.

Definitions (all weights normalised to sum 1):

* ``mean``: weighted mean of x and y; circular mean of theta
  (``atan2(sum w sin, sum w cos)``), wrapped to ``[-pi, pi)``.
* ``cov``: 3x3 weighted covariance of ``(x - mx, y - my, wrap(theta - mtheta))``
  (the heading residuals are wrapped, so a cloud straddling ``±pi`` is tight).
* ``ess``: Kish's effective sample size ``1 / sum w^2``.
* ``entropy_nats``: Shannon entropy (natural log) of the weight histogram over
  coarse pose bins of ``entropy_bin_xy_m`` x ``entropy_bin_xy_m`` x
  ``entropy_bin_theta_rad`` (defaults 0.5 m x 0.5 m x pi/8 rad = 22.5 deg). A single
  bin gives 0; a spread-out belief gives up to ``log(#bins)``.
* ``n_clusters``: connected components (8-neighbourhood) of the coarse ``(x, y)``
  bins (``cluster_bin_m``, default 0.5 m) that hold at least one particle, counting
  only components whose total weight is at least ``cluster_min_weight``
  (default 0.02), so stray particles do not count as hypotheses.
* ``converged``: position std ``sqrt(var_x + var_y) < converged_pos_std_m`` and
  heading std ``sqrt(var_theta) < converged_theta_std_rad``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from filters.pose import wrap_angle
from filters.smc.resampling import normalise_weights


@dataclass(frozen=True)
class BeliefConfig:
    """Bin sizes and thresholds of :func:`summarize` (see the module docstring)."""

    entropy_bin_xy_m: float = 0.5
    entropy_bin_theta_rad: float = math.pi / 8
    cluster_bin_m: float = 0.5
    cluster_min_weight: float = 0.02
    converged_pos_std_m: float = 0.3
    converged_theta_std_rad: float = 0.2

    def __post_init__(self) -> None:
        for name in (
            "entropy_bin_xy_m",
            "entropy_bin_theta_rad",
            "cluster_bin_m",
            "converged_pos_std_m",
            "converged_theta_std_rad",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"BeliefConfig.{name} must be a positive number, got {v!r}")
        if not (isinstance(self.cluster_min_weight, (int, float)) and 0 <= self.cluster_min_weight <= 1):
            raise ValueError(f"BeliefConfig.cluster_min_weight must be in [0, 1], got {self.cluster_min_weight!r}")


@dataclass(frozen=True, eq=False)
class Belief:
    """Summary of a weighted particle set (units: metres, radians, nats).

    Attributes:
        mean: ``(3,)`` mean pose ``(x, y, theta)``.
        cov: ``(3, 3)`` covariance of ``(x, y, theta)`` with wrapped heading residuals.
        ess: effective sample size, in ``[1, N]``.
        n_particles: N.
        entropy_nats: entropy of the coarse pose histogram.
        n_clusters: number of position hypotheses (see module docstring).
        pos_std_m: ``sqrt(cov_xx + cov_yy)``.
        theta_std_rad: ``sqrt(cov_thth)``.
        converged: both stds below the config thresholds.
    """

    mean: np.ndarray
    cov: np.ndarray
    ess: float
    n_particles: int
    entropy_nats: float
    n_clusters: int
    pos_std_m: float
    theta_std_rad: float
    converged: bool

    def as_dict(self) -> dict:
        """Plain Python values (floats, ints, bools, nested lists) for a Gymnasium ``info``."""
        return {
            "mean": [float(v) for v in self.mean],
            "cov": [[float(v) for v in row] for row in self.cov],
            "ess": float(self.ess),
            "n_particles": int(self.n_particles),
            "entropy_nats": float(self.entropy_nats),
            "n_clusters": int(self.n_clusters),
            "pos_std_m": float(self.pos_std_m),
            "theta_std_rad": float(self.theta_std_rad),
            "converged": bool(self.converged),
        }


def _normalised(weights: np.ndarray, n: int) -> np.ndarray:
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (n,):
        raise ValueError(f"weights must have shape ({n},), got {w.shape}")
    return normalise_weights(w)


def _bin_keys(values: np.ndarray, size: float) -> np.ndarray:
    return np.floor(values / size).astype(np.int64)


def linear_bin_keys(*keys: np.ndarray) -> np.ndarray:
    """One int64 key per particle from several integer bin indices (offset to start at 0)."""
    out = np.zeros(keys[0].shape, dtype=np.int64)
    for k in keys:
        k0 = k - k.min()
        out = out * (int(k0.max()) + 1) + k0
    return out


def summarize(poses: np.ndarray, weights: np.ndarray, config: BeliefConfig | None = None) -> Belief:
    """Summarise ``poses (N, 3)`` with non-negative ``weights (N,)`` (normalised here).

    Raises:
        ValueError: no particles, bad shapes, or weights that are negative, non-finite or all zero.
    """
    cfg = config if config is not None else BeliefConfig()
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {p.shape}")
    n = p.shape[0]
    if n == 0:
        raise ValueError("no particles to summarise")
    w = _normalised(weights, n)

    mx, my = float(w @ p[:, 0]), float(w @ p[:, 1])
    mth = float(wrap_angle(np.arctan2(w @ np.sin(p[:, 2]), w @ np.cos(p[:, 2]))))
    res = np.stack([p[:, 0] - mx, p[:, 1] - my, wrap_angle(p[:, 2] - mth)], axis=1)
    cov = (res * w[:, None]).T @ res
    cov = 0.5 * (cov + cov.T)
    ess = float(1.0 / np.sum(w * w))

    # entropy of the coarse (x, y, theta) histogram
    keys = linear_bin_keys(
        _bin_keys(p[:, 0], cfg.entropy_bin_xy_m),
        _bin_keys(p[:, 1], cfg.entropy_bin_xy_m),
        _bin_keys(wrap_angle(p[:, 2]) + math.pi, cfg.entropy_bin_theta_rad),
    )
    _, inv = np.unique(keys, return_inverse=True)
    mass = np.bincount(inv.reshape(-1), weights=w)
    mass = mass[mass > 0]
    entropy = float(-(mass * np.log(mass)).sum())

    n_clusters = _count_clusters(p[:, :2], w, cfg.cluster_bin_m, cfg.cluster_min_weight)

    pos_std = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    th_std = math.sqrt(max(cov[2, 2], 0.0))
    mean = np.array([mx, my, mth])
    mean.setflags(write=False)
    cov.setflags(write=False)
    return Belief(
        mean=mean,
        cov=cov,
        ess=ess,
        n_particles=n,
        entropy_nats=max(entropy, 0.0),
        n_clusters=n_clusters,
        pos_std_m=pos_std,
        theta_std_rad=th_std,
        converged=bool(pos_std < cfg.converged_pos_std_m and th_std < cfg.converged_theta_std_rad),
    )


def _count_clusters(xy: np.ndarray, w: np.ndarray, bin_m: float, min_weight: float) -> int:
    """Connected components (8-neighbourhood) of occupied coarse (x, y) bins with weight >= min_weight."""
    ix = _bin_keys(xy[:, 0], bin_m)
    iy = _bin_keys(xy[:, 1], bin_m)
    ix -= ix.min()
    iy -= iy.min()
    shape = (int(iy.max()) + 1, int(ix.max()) + 1)
    if shape[0] * shape[1] > 4_000_000:  # absurdly spread cloud: fall back to a coarser raster
        return _count_clusters(xy, w, bin_m * 4.0, min_weight)
    mass = np.bincount(iy * shape[1] + ix, weights=w, minlength=shape[0] * shape[1]).reshape(shape)
    occupied = np.zeros(shape, dtype=bool)
    occupied[iy, ix] = True
    labels, n_comp = ndimage.label(occupied, structure=np.ones((3, 3), dtype=bool))
    if n_comp == 0:
        return 0
    comp_mass = ndimage.sum_labels(mass, labels, index=np.arange(1, n_comp + 1))
    return int(np.sum(comp_mass >= min_weight - 1e-12))
