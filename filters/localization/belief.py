"""Belief summary of a weighted particle set: what a filter currently holds, honestly.

`summarize` turns ``(N, 3)`` poses and ``(N,)`` weights into a frozen
`Belief` whose `Belief.as_dict` is plain Python (floats, ints,
lists), ready for a Gymnasium ``info`` dict. `cluster_labels` is the
clustering it uses, shared with the filter's clustered resampling.

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
* **hypotheses**: the particles are binned on a ``cluster_bin_m`` x ``cluster_bin_m`` x
  ``cluster_bin_theta_rad`` raster (defaults 0.5 m x 0.5 m x 45 deg, heading
  wrapping around); a *cluster* is a connected component of the bins holding at least
  ``cluster_min_bin_frac`` (default 0.05) times the mean weight of the bins that hold
  particles (26-neighbourhood, across the ``±pi`` seam too); particles in lighter bins
  belong to no hypothesis. Each cluster whose total weight is
  at least ``cluster_min_weight`` (default 0.02, so stray particles are no
  hypothesis) is a `Hypothesis` — weight, mean, covariance, particle count —
  and ``hypotheses`` lists them by weight, heaviest first. ``n_clusters`` is their number.
* ``converged``: *one hypothesis holds nearly all the mass and is tight*: the heaviest
  hypothesis has weight ``>= converged_min_weight`` (default 0.95), position std
  ``sqrt(var_x + var_y) < converged_pos_std_m`` (0.3 m) and heading std
  ``< converged_theta_std_rad`` (0.2 rad). A cloud split over two look-alike places
  is never converged, however tight each part is. (``converged_rule="spread"`` restores
  the rule of the first release, kept for comparisons: the *whole* set's stds below the
  same thresholds, whatever its hypotheses.) `summarize` judges the set it is given;
  `filters.localization.mcl.MonteCarloLocalizer.belief` can also ask that the criterion held
  after each of the last ``converged_min_updates`` measurement updates (default 1: the current
  set only), so that places the filter's proposals have only just put particles on get a few
  updates to show themselves before one place is called certain; and with
  ``converged_hold_weight`` (default None: off) it *holds* a convergence: once called converged,
  the belief stays so while its heaviest hypothesis lies at the same place (within
  ``2 * cluster_bin_m`` and ``cluster_bin_theta_rad`` of the hypothesis last called converged) with
  weight ``>= converged_hold_weight`` and the same spread limits. Without it the flag flickers:
  the relocalizer's routine proposals take a few percent of the mass at every update, so a
  belief at the truth hovers around the 0.95 it needs.

Cost: O(N) plus the raster (the particles' bounding box), every step.

Backends: every function here takes ``backend="numba"`` (default; the kernels of
`filters.localization.belief_kernels`) or ``backend="numpy"`` (the reference, kept as the
specification). Both give the same results *bit for bit* — labels, counts and every float —
because the kernels repeat the reference's floating-point operations in the same order and
leave BLAS dot products, pairwise sums and transcendental functions to NumPy
(``tests/test_belief_kernels.py``); the weighted means are `filters._blas.dot` in both, a fixed
order that does not depend on OpenBLAS's thread count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from filters import _blas
from filters.localization import belief_kernels as _k
from filters.numbers import is_int, is_real
from filters.pose import compose_floats, finite_increment, wrap_angle, wrap_float
from filters.smc.resampling import normalise_weights

_MAX_RASTER_CELLS = 4_000_000
_SAFE_SUM = 1e300
"""`_normalised` sums weights whose largest is at most this over their count directly: their sum cannot overflow."""
_NO_WEIGHTS = np.zeros(0)
BACKENDS = ("numba", "numpy")


def _check_backend(backend: str) -> None:
    if backend not in BACKENDS:
        raise ValueError(f"belief backend must be one of {BACKENDS}, got {backend!r}")


MIN_BIN_THETA_RAD = 2.0 * math.pi / 3600
"""Narrowest heading bin of the pose rasters (0.1 deg, 3600 a turn): 1e-7 rad made 63 million heading bins, which
no coarsening of the position bins could fit (the clustering recursed without end)."""


@dataclass(frozen=True)
class BeliefConfig:
    """Bin sizes and thresholds of `summarize` (see the module docstring)."""

    entropy_bin_xy_m: float = 0.5
    entropy_bin_theta_rad: float = math.pi / 8
    cluster_bin_m: float = 0.5
    cluster_bin_theta_rad: float = math.pi / 4
    cluster_min_weight: float = 0.02
    cluster_min_bin_frac: float = 0.05
    converged_min_weight: float = 0.95
    converged_pos_std_m: float = 0.3
    converged_theta_std_rad: float = 0.2
    converged_rule: str = "hypothesis"
    converged_min_updates: int = 1
    converged_hold_weight: float | None = None

    def __post_init__(self) -> None:
        k = self.converged_min_updates
        if not is_int(k) or k < 1:
            raise ValueError(f"BeliefConfig.converged_min_updates must be an int >= 1, got {k!r}")
        if self.converged_rule not in ("hypothesis", "spread"):
            raise ValueError(
                f"BeliefConfig.converged_rule must be 'hypothesis' or 'spread', got {self.converged_rule!r}"
            )
        for name in (
            "entropy_bin_xy_m",
            "entropy_bin_theta_rad",
            "cluster_bin_m",
            "cluster_bin_theta_rad",
            "converged_pos_std_m",
            "converged_theta_std_rad",
        ):
            v = getattr(self, name)
            if not (is_real(v) and math.isfinite(v) and v > 0):
                raise ValueError(f"BeliefConfig.{name} must be a positive number, got {v!r}")
            if name.endswith("bin_theta_rad") and v < MIN_BIN_THETA_RAD:
                raise ValueError(
                    f"BeliefConfig.{name} must be at least MIN_BIN_THETA_RAD = 2 pi / 3600 (0.1 deg), got {v!r}"
                )
            object.__setattr__(self, name, float(v))
        for name in ("cluster_min_weight", "cluster_min_bin_frac", "converged_min_weight"):
            v = getattr(self, name)
            if not (is_real(v) and 0 <= v <= 1):
                raise ValueError(f"BeliefConfig.{name} must be in [0, 1], got {v!r}")
            object.__setattr__(self, name, float(v))
        h = self.converged_hold_weight
        if h is not None:
            if not (is_real(h) and 0 < h <= self.converged_min_weight and self.converged_rule == "hypothesis"):
                raise ValueError(
                    "BeliefConfig.converged_hold_weight must be None (no hold) or a number in "
                    f"(0, converged_min_weight] with converged_rule 'hypothesis'; got {h!r} with converged_min_weight "
                    f"{self.converged_min_weight!r} and rule {self.converged_rule!r} (SemReloc-v6 and -v7 hold at "
                    "0.85: "
                    "to lower converged_min_weight below it or use the 'spread' rule, also set converged_hold_weight)"
                )
            object.__setattr__(self, "converged_hold_weight", float(h))


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """One cluster of the particle set (units: metres, radians).

    A cluster is a connected patch of occupied pose-histogram bins, so a set spread over the whole map
    (as after a global reset) is one wide hypothesis of weight ~1: read its weight with its spread
    (`pos_std_m`), as the "converged" test does.

    Attributes:
        weight: total normalised weight of its particles, in ``(0, 1]`` (a sum of rounded weights: it can
            exceed 1 by a few ulps; an outside fuzzer saw 1.0000000000000009).
        mean: ``(3,)`` weighted mean pose (circular mean of theta).
        cov: ``(3, 3)`` weighted covariance about ``mean`` (wrapped heading residuals).
        n_particles: particles in the cluster.
    """

    weight: float
    mean: np.ndarray
    cov: np.ndarray
    n_particles: int

    @property
    def pos_std_m(self) -> float:
        return math.sqrt(max(self.cov[0, 0] + self.cov[1, 1], 0.0))

    @property
    def theta_std_rad(self) -> float:
        return math.sqrt(max(self.cov[2, 2], 0.0))

    def as_dict(self) -> dict:
        return {
            "weight": float(self.weight),
            "mean": _floats(self.mean),
            "cov": _floats(self.cov),
            "n_particles": int(self.n_particles),
        }


@dataclass(frozen=True, eq=False)
class Belief:
    """Summary of a weighted particle set (units: metres, radians, nats).

    Attributes:
        mean: ``(3,)`` mean pose ``(x, y, theta)`` of the whole set.
        cov: ``(3, 3)`` covariance of ``(x, y, theta)`` with wrapped heading residuals.
        ess: effective sample size, in ``[1, N]``.
        n_particles: N.
        entropy_nats: entropy of the coarse pose histogram.
        n_clusters: number of hypotheses (``len(hypotheses)``).
        pos_std_m: ``sqrt(cov_xx + cov_yy)`` of the whole set.
        theta_std_rad: ``sqrt(cov_thth)`` of the whole set.
        converged: one tight hypothesis holds nearly all the mass (module docstring).
        hypotheses: the clusters by weight, heaviest first (module docstring).
        estimate: ``(3,)`` the pose estimate: the heaviest hypothesis's mean (as AMCL reports
            its heaviest cluster), or ``mean`` when no cluster reaches ``cluster_min_weight``.
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
    hypotheses: tuple[Hypothesis, ...] = ()
    estimate: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.estimate is None:
            object.__setattr__(self, "estimate", self.mean)

    @property
    def best(self) -> Hypothesis | None:
        """The heaviest hypothesis (None if no cluster reaches ``cluster_min_weight``)."""
        return self.hypotheses[0] if self.hypotheses else None

    def as_dict(self, max_hypotheses: int = 8) -> dict:
        """Plain Python values (floats, ints, bools, nested lists) for a Gymnasium ``info``;
        at most ``max_hypotheses`` hypotheses are listed (``n_clusters`` counts them all)."""
        return {
            "mean": _floats(self.mean),
            "cov": _floats(self.cov),
            "estimate": _floats(self.estimate),
            "ess": float(self.ess),
            "n_particles": int(self.n_particles),
            "entropy_nats": float(self.entropy_nats),
            "n_clusters": int(self.n_clusters),
            "pos_std_m": float(self.pos_std_m),
            "theta_std_rad": float(self.theta_std_rad),
            "converged": bool(self.converged),
            "hypotheses": [h.as_dict() for h in self.hypotheses[:max_hypotheses]],
        }


MAX_POSE_M = 1e15
"""Largest distance of a pose from the map origin `summarize` takes (m): its rasters number cells of 0.5 m in
int64, which overflows near 4.6e18 m; no map in metres comes near it."""
_POSE_LIMIT = np.array([MAX_POSE_M, MAX_POSE_M, np.inf])


def _floats(values) -> list:
    """``values`` as (nested) lists of Python floats: the numbers of ``float(v)`` for each entry."""
    return np.asarray(values, dtype=np.float64).tolist()


def _normalised(weights: np.ndarray, n: int) -> np.ndarray:
    """`normalise_weights` of ``weights`` ``(n,)``, the same bits: one compiled pass checks them and finds the
    largest, and `normalise_weights` itself runs only for weights it must refuse or whose sum could overflow."""
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.shape != (n,):
        raise ValueError(f"weights must have shape ({n},), got {w.shape}")
    return _normalised_checked(w, *_k.finite_non_negative_max(np.ascontiguousarray(w)))


def _normalised_checked(w: np.ndarray, ok: bool, largest: float) -> np.ndarray:
    """`_normalised` of ``(n,)`` weights ``w`` whose `filters.localization.belief_kernels.finite_non_negative_max`
    is ``(ok, largest)``."""
    if not (ok and 0.0 < largest <= _SAFE_SUM / w.shape[0]):
        return normalise_weights(w)
    return w / w.sum()


def _bin_keys(values: np.ndarray, size: float) -> np.ndarray:
    return np.floor(values / size).astype(np.int64)


def linear_bin_keys(*keys: np.ndarray) -> np.ndarray:
    """One int64 key per particle from several integer bin indices (offset to start at 0)."""
    out = np.zeros(keys[0].shape, dtype=np.int64)
    for k in keys:
        k0 = k - k.min()
        out = out * (int(k0.max()) + 1) + k0
    return out


def heading_bins(theta: np.ndarray, bin_rad: float) -> tuple[np.ndarray, int]:
    """``(bin index per heading, n)``: ``n = round(2 pi / bin_rad)`` (at least 1) bins over ``[-pi, pi)``."""
    n = max(1, round(2.0 * math.pi / bin_rad))
    k = np.floor((wrap_angle(theta) + math.pi) * (n / (2.0 * math.pi))).astype(np.int64)
    return np.minimum(k, n - 1), n


def histogram_entropy(
    poses: np.ndarray, w: np.ndarray, bin_xy_m: float, bin_theta_rad: float, backend: str = "numba"
) -> float:
    """Shannon entropy (nats) of normalised weights ``w`` over the coarse pose bins."""
    _check_backend(backend)
    if backend == "numba":
        p = np.ascontiguousarray(poses, dtype=np.float64)
        nt, scale = _k.heading_scale(bin_theta_rad)
        ww = np.ascontiguousarray(w, dtype=np.float64)
        mass, fits = _k.entropy_masses(p, ww, float(bin_xy_m), nt, scale, _MAX_RASTER_CELLS)
        if fits:
            return _entropy_of(mass)
        return histogram_entropy(poses, w, bin_xy_m, bin_theta_rad, "numpy")
    ix = _bin_keys(poses[:, 0], bin_xy_m)
    iy = _bin_keys(poses[:, 1], bin_xy_m)
    it, nt = heading_bins(poses[:, 2], bin_theta_rad)
    ix -= ix.min()
    iy -= iy.min()
    nx, ny = int(ix.max()) + 1, int(iy.max()) + 1
    if nx * ny * nt <= _MAX_RASTER_CELLS:
        mass = np.bincount((iy * nx + ix) * nt + it, weights=w, minlength=nx * ny * nt)
    else:  # absurdly spread cloud: sort instead of a dense raster
        _, inv = np.unique(linear_bin_keys(ix, iy, it), return_inverse=True)
        mass = np.bincount(inv.reshape(-1), weights=w)
    return _entropy_of(mass[mass > 0])


def _entropy_of(mass: np.ndarray) -> float:
    """Shannon entropy (nats) of the positive bin masses ``mass`` (normalised weights summed per bin)."""
    return max(float(-(mass * np.log(mass)).sum()), 0.0)


def cluster_labels(
    poses: np.ndarray,
    bin_m: float,
    bin_theta_rad: float,
    weights: np.ndarray | None = None,
    min_bin_frac: float = 0.0,
    backend: str = "numba",
) -> tuple[np.ndarray, int]:
    """``(labels (N,), n)``: the connected cluster (``0 .. n-1``) of every particle, or -1.

    Clusters are connected components of the occupied cells of a ``bin_m`` x ``bin_m`` x
    ``bin_theta_rad`` raster (26-neighbourhood, heading wrapping around ``±pi``). A cell is
    occupied when its particles' normalised ``weights`` sum to at least ``min_bin_frac`` times
    the mean weight of the cells that hold particles (any particle, when 0 or no weights);
    particles in other cells get label -1, so a thin haze of unlikely particles does not join
    two hypotheses, while a uniform cloud stays one cluster on a map of any size.
    """
    _check_backend(backend)
    if backend == "numba":
        return _cluster_labels_numba(poses, bin_m, bin_theta_rad, weights, min_bin_frac)
    p = np.asarray(poses, dtype=np.float64)
    ix = _bin_keys(p[:, 0], bin_m)
    iy = _bin_keys(p[:, 1], bin_m)
    ix -= ix.min()
    iy -= iy.min()
    nx, ny = int(ix.max()) + 1, int(iy.max()) + 1
    it, nt = heading_bins(p[:, 2], bin_theta_rad)
    if nx * ny * nt > _MAX_RASTER_CELLS:  # absurdly spread cloud: coarser raster
        return cluster_labels(p, bin_m * 4.0, bin_theta_rad, weights, min_bin_frac, "numpy")
    if weights is not None and min_bin_frac > 0:
        mass = np.bincount((iy * nx + ix) * nt + it, weights=weights, minlength=nx * ny * nt)
        held = np.bincount((iy * nx + ix) * nt + it, minlength=nx * ny * nt) > 0
        occupied = (mass >= min_bin_frac * mass.sum() / held.sum()) & held
        occupied = occupied.reshape(ny, nx, nt)
    else:
        occupied = np.zeros((ny, nx, nt), dtype=bool)
        occupied[iy, ix, it] = True
    lab, n = ndimage.label(occupied, structure=np.ones((3, 3, 3), dtype=bool))
    if nt > 2 and n > 1:  # join components that touch across the heading seam
        first = np.pad(lab[:, :, 0], 1)
        last = lab[:, :, -1]
        src, dst = [], []
        for dy in (0, 1, 2):
            for dx in (0, 1, 2):
                a = first[dy : dy + ny, dx : dx + nx]
                both = (a > 0) & (last > 0)
                src.append(a[both])
                dst.append(last[both])
        src = np.concatenate(src)
        if src.size:
            dst = np.concatenate(dst)
            graph = coo_matrix((np.ones(src.size), (src, dst)), shape=(n + 1, n + 1))
            _, comp = connected_components(graph, directed=False)
            used = np.unique(comp[1:])
            remap = np.searchsorted(used, comp)
            lab = remap[lab] + 1
            lab[~occupied] = 0
            n = used.size
    return lab[iy, ix, it].astype(np.int64) - 1, int(n)


def _cluster_labels_numba(poses, bin_m, bin_theta_rad, weights, min_bin_frac) -> tuple[np.ndarray, int]:
    p = np.ascontiguousarray(poses, dtype=np.float64)
    nt, scale = _k.heading_scale(bin_theta_rad)
    by_mass = weights is not None and min_bin_frac > 0  # else the reference ignores the weights (NaN ones too)
    w = np.ascontiguousarray(weights, dtype=np.float64) if by_mass else np.zeros(p.shape[0])
    cell, mass, count, nx, ny, held, fits = _k.cluster_raster(p, w, float(bin_m), nt, scale, _MAX_RASTER_CELLS)
    if not fits:  # absurdly spread cloud: coarser raster, as the reference
        return _cluster_labels_numba(p, bin_m * 4.0, bin_theta_rad, weights, min_bin_frac)
    labels, n = _k.cell_labels(mass, count, _threshold(mass, held, min_bin_frac, by_mass), ny, nx, nt, cell)
    return labels, int(n)


def _threshold(mass: np.ndarray, held: int, min_bin_frac: float, by_mass: bool) -> float:
    """The mass a raster cell needs to be occupied (`cluster_labels`): ``min_bin_frac`` times the mean mass of the
    ``held`` cells with particles, with the reference's NumPy reduction (a pairwise sum over the raster), or -inf
    (any cell with particles) when not ``by_mass``."""
    return float(min_bin_frac * mass.sum() / held) if by_mass else -math.inf


def cluster_stats(
    poses: np.ndarray, w: np.ndarray, labels: np.ndarray, n: int, backend: str = "numba"
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-cluster ``(weight (n,), mean (n, 3), cov (n, 3, 3), count (n,))`` of normalised weights ``w``.

    Particles labelled -1 belong to no cluster. A cluster with zero weight gets its particles'
    unweighted mean and covariance.
    """
    _check_backend(backend)
    if backend == "numba":
        p = np.ascontiguousarray(poses, dtype=np.float64)
        th = p[:, 2]
        return _cluster_stats_numba(
            p,
            np.ascontiguousarray(w, dtype=np.float64),
            np.ascontiguousarray(labels, dtype=np.int64),
            n,
            np.sin(th),
            np.cos(th),
        )
    inside = labels >= 0
    if not inside.all():
        poses, w, labels = poses[inside], w[inside], labels[inside]
    x, y, th = np.ascontiguousarray(poses.T)
    count = np.bincount(labels, minlength=n)
    weight = np.bincount(labels, weights=w, minlength=n).astype(np.float64, copy=False)  # int64 with no particle
    ww = np.where((weight > 0)[labels], w, 1.0 / np.maximum(count[labels], 1))
    wsum = np.where(weight > 0, weight, 1.0)
    mean = np.empty((n, 3))
    mean[:, 0] = np.bincount(labels, weights=ww * x, minlength=n) / wsum
    mean[:, 1] = np.bincount(labels, weights=ww * y, minlength=n) / wsum
    s = np.bincount(labels, weights=ww * np.sin(th), minlength=n)
    c = np.bincount(labels, weights=ww * np.cos(th), minlength=n)
    mean[:, 2] = wrap_angle(np.arctan2(s, c))
    r = np.stack([x - mean[labels, 0], y - mean[labels, 1], wrap_angle(th - mean[labels, 2])])
    cov = np.empty((n, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            v = np.bincount(labels, weights=ww * r[a] * r[b], minlength=n) / wsum
            cov[:, a, b] = v
            cov[:, b, a] = v
    return weight, mean, cov, count


def _cluster_stats_numba(p, w, labels, n, sin_th, cos_th):
    count, weight, wsum, sums, order, starts = _k.cluster_sums(labels, n, p, sin_th, cos_th, w)
    mean = _cluster_means(sums, wsum)
    cov = _k.cluster_covariances(order, starts, p, w, count, weight, wsum, mean)
    return weight, mean, cov, count


def _cluster_means(sums: np.ndarray, wsum: np.ndarray) -> np.ndarray:
    """``(n, 3)`` cluster means from `filters.localization.belief_kernels.cluster_sums`' ``sums`` and ``wsum`` (the
    reference's divisions, and its ``arctan2`` in NumPy)."""
    mean = np.empty((sums.shape[0], 3))
    mean[:, 0] = sums[:, 0] / wsum
    mean[:, 1] = sums[:, 1] / wsum
    mean[:, 2] = wrap_angle(np.arctan2(sums[:, 2], sums[:, 3]))
    return mean


def holds_as_converged(h: Hypothesis, cfg: BeliefConfig, min_weight: float) -> bool:
    """Whether hypothesis ``h`` weighs at least ``min_weight`` and is as tight as "converged" asks
    (``converged_pos_std_m``, ``converged_theta_std_rad``): the ``"hypothesis"`` rule with
    ``converged_min_weight``, and a held convergence with ``converged_hold_weight``."""
    tight = h.pos_std_m < cfg.converged_pos_std_m and h.theta_std_rad < cfg.converged_theta_std_rad
    return bool(h.weight >= min_weight and tight)


def _carried_pose(mean: np.ndarray, cov: np.ndarray, dx: float, dy: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(mean, cov)`` carried by the robot-frame increment ``(dx, dy, dt)`` (`carried`), read-only, in Python floats:
    a handful of poses per step, where NumPy's per-call cost would outweigh the arithmetic."""
    x, y, t = mean.tolist()
    pose = compose_floats(x, y, t, dx, dy, dt)
    c, s = math.cos(t), math.sin(t)  # the C library's, as NumPy's float64 cos and sin (filters.pose.cos_sin)
    (sxx, sxy, sxt), (_, syy, syt), (_, _, stt) = cov.tolist()
    a, b = -s * dx - c * dy, c * dx - s * dy  # d(x, y)/d(theta): J = [[1, 0, a], [0, 1, b], [0, 0, 1]]
    xt, yt = sxt + a * stt, syt + b * stt
    xy = sxy + a * syt + b * sxt + a * b * stt
    xx, yy = sxx + 2.0 * a * sxt + a * a * stt, syy + 2.0 * b * syt + b * b * stt
    if not all(map(math.isfinite, (*pose, xx, yy, xy, xt, yt))):
        raise ValueError(f"the increment {(dx, dy, dt)} carries the belief to non-finite poses or covariances")
    moved = np.array(pose)
    out = np.array([[xx, xy, xt], [xy, yy, yt], [xt, yt, stt]])
    moved.setflags(write=False)
    out.setflags(write=False)
    return moved, out


def carried(belief: Belief, delta, config: BeliefConfig | None = None) -> Belief:
    """``belief`` carried by the robot-frame odometry increment ``delta = (dx m, dy m, dtheta rad)``: what a filter
    reports between its measurement updates without summarising its moved set again (as AMCL reports the pose of its
    last update composed with the odometry since).

    Every mean (the set's, each hypothesis's, the estimate) is composed with ``delta`` (`filters.pose.compose`), every
    covariance becomes ``J cov J^T`` with ``J`` the Jacobian of that composition at its mean (the heading's
    uncertainty swings the position by the distance moved), and ``converged`` is judged again by ``config``'s rule
    (default `BeliefConfig`) on the carried covariances. The entropy, ESS and the particle and cluster counts are
    ``belief``'s. No motion noise is added: the carried belief is as certain as the last update left it, where the
    moved set itself spreads by the motion model's noise. A zero ``delta`` returns ``belief`` itself.

    Raises:
        ValueError: ``delta`` is not 3 finite numbers, or carries a mean or covariance to non-finite values.
    """
    cfg = config if config is not None else BeliefConfig()
    dx, dy, dt = finite_increment(delta)
    if dx == 0.0 and dy == 0.0 and dt == 0.0:
        return belief
    mean, cov = _carried_pose(belief.mean, belief.cov, dx, dy, dt)
    hyps = []
    for h in belief.hypotheses:
        m, c = _carried_pose(h.mean, h.cov, dx, dy, dt)
        hyps.append(Hypothesis(weight=h.weight, mean=m, cov=c, n_particles=h.n_particles))
    return _judged(mean, cov, hyps, cfg, belief.ess, belief.n_particles, belief.entropy_nats)


def _judged(
    mean: np.ndarray, cov: np.ndarray, hyps: list[Hypothesis], cfg: BeliefConfig, ess: float, n: int, entropy: float
) -> Belief:
    """The `Belief` of a set's read-only ``mean`` and ``cov`` and its hypotheses (heaviest first), with its spread,
    estimate and "converged" judged by ``cfg``'s rule (the module docstring)."""
    best = hyps[0] if hyps else None
    pos_std = math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))
    th_std = math.sqrt(max(cov[2, 2], 0.0))
    if cfg.converged_rule == "spread":
        converged = bool(pos_std < cfg.converged_pos_std_m and th_std < cfg.converged_theta_std_rad)
    else:
        converged = best is not None and holds_as_converged(best, cfg, cfg.converged_min_weight)
    return Belief(
        mean=mean,
        cov=cov,
        ess=ess,
        n_particles=n,
        entropy_nats=entropy,
        n_clusters=len(hyps),
        pos_std_m=pos_std,
        theta_std_rad=th_std,
        converged=converged,
        hypotheses=tuple(hyps),
        estimate=mean if best is None or cfg.converged_rule == "spread" else best.mean,
    )


def summarize(
    poses: np.ndarray, weights: np.ndarray, config: BeliefConfig | None = None, backend: str = "numba"
) -> Belief:
    """Summarise ``poses (N, 3)`` with non-negative ``weights (N,)`` (normalised here).

    ``backend``: ``"numba"`` or ``"numpy"`` (reference); the same Belief bit for bit.

    Raises:
        ValueError: no particles, bad shapes, or weights that are negative, non-finite or all zero,
            or an unknown backend.
    """
    _check_backend(backend)
    cfg = config if config is not None else BeliefConfig()
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {p.shape}")
    n = p.shape[0]
    if n == 0:
        raise ValueError("no particles to summarise")
    summary = _summary_numba if backend == "numba" else _summary_numpy
    mean, cov, ess, entropy, cw, cmean, ccov, ccount, keep = summary(p, weights, cfg)
    cmean.setflags(write=False)  # the hypotheses' means and covariances are read-only views of these
    ccov.setflags(write=False)
    weights, counts = cw.tolist(), ccount.tolist()
    hyps = [Hypothesis(weight=weights[k], mean=cmean[k], cov=ccov[k], n_particles=counts[k]) for k in keep]
    mean.setflags(write=False)
    cov.setflags(write=False)
    return _judged(mean, cov, hyps, cfg, ess, n, entropy)


def _refuse_poses(p: np.ndarray) -> None:
    """Raise for poses that are not all finite and within `MAX_POSE_M` of the origin (`summarize`)."""
    if not np.isfinite(p).all():
        raise ValueError("poses contain NaN or inf")
    raise ValueError(
        f"poses lie {np.abs(p[:, :2]).max():.3g} m from the origin, beyond the {MAX_POSE_M:g} m the pose rasters "
        "take (not metres?)"
    )


def _summary_numpy(p: np.ndarray, weights, cfg: BeliefConfig) -> tuple:
    """`summarize`'s figures by the NumPy reference: ``(mean, cov, ess, entropy, cluster weights, means,
    covariances, counts, the hypotheses' clusters heaviest first)``."""
    if not (np.abs(p) < _POSE_LIMIT).all():
        _refuse_poses(p)
    w = _normalised(weights, p.shape[0])
    x, y, th = np.ascontiguousarray(p.T)  # contiguous rows: strided dot products are far slower
    dot = _blas.dot  # both backends: one order whatever the BLAS thread count
    mx, my = float(dot(w, x)), float(dot(w, y))
    mth = wrap_float(float(np.arctan2(dot(w, np.sin(th)), dot(w, np.cos(th)))))
    res = np.stack([x - mx, y - my, wrap_angle(th - mth)])
    cov = (res * w) @ res.T
    entropy = histogram_entropy(p, w, cfg.entropy_bin_xy_m, cfg.entropy_bin_theta_rad, "numpy")
    labels, n = cluster_labels(p, cfg.cluster_bin_m, cfg.cluster_bin_theta_rad, w, cfg.cluster_min_bin_frac, "numpy")
    cw, cmean, ccov, ccount = cluster_stats(p, w, labels, n, "numpy")
    keep = np.flatnonzero((cw >= cfg.cluster_min_weight - 1e-12) & (cw > 0))  # a hypothesis has weight (0, 1]
    keep = keep[np.argsort(-cw[keep], kind="stable")].tolist()
    mean, ess = np.array([mx, my, mth]), float(1.0 / np.sum(w * w))
    return mean, 0.5 * (cov + cov.T), ess, entropy, cw, cmean, ccov, ccount, keep


def _summary_numba(p: np.ndarray, weights, cfg: BeliefConfig) -> tuple:
    """`_summary_numpy`'s figures, the same bits, from four compiled calls (`belief_kernels.summary_inputs`,
    `summary_rasters`, `summary_clusters`, `summary_covariances`) with NumPy between them for what must stay NumPy's:
    the weights' sum, the BLAS dot products and covariance, logs, pairwise sums and arctan2."""
    n = p.shape[0]
    pc = np.ascontiguousarray(p)
    # float64 weights of the right shape are checked in the first call; any others after the poses, as the
    # reference converts and refuses them (a conversion may warn or raise)
    early = isinstance(weights, np.ndarray) and weights.dtype == np.float64 and weights.size == n
    w = weights.reshape(-1) if early else None
    xyt, cos_th, sin_th = np.empty((3, n)), np.empty(n), np.empty(n)
    raw = np.ascontiguousarray(w) if early else _NO_WEIGHTS
    in_limit, ok, largest = _k.summary_inputs(pc, raw, MAX_POSE_M, xyt, cos_th, sin_th)
    if not in_limit:
        _refuse_poses(p)
    w = _normalised_checked(w, ok, largest) if early else _normalised(weights, n)
    x, y, _ = xyt
    dot = _blas.dot
    mx, my = float(dot(w, x)), float(dot(w, y))
    mth = wrap_float(float(np.arctan2(dot(w, sin_th), dot(w, cos_th))))
    res = np.empty((3, n))
    wc = np.ascontiguousarray(w)
    e_nt, e_scale = _k.heading_scale(cfg.entropy_bin_theta_rad)
    c_nt, c_scale = _k.heading_scale(cfg.cluster_bin_theta_rad)
    masses, e_fits, cell, mass, count, nx, ny, held, c_fits = _k.summary_rasters(
        pc, wc, mx, my, mth, res, float(cfg.entropy_bin_xy_m), e_nt, e_scale, float(cfg.cluster_bin_m), c_nt, c_scale,
        _MAX_RASTER_CELLS,
    )  # fmt: skip
    cov = (res * w) @ res.T
    if e_fits:
        entropy = _entropy_of(masses)
    else:  # absurdly spread cloud
        entropy = histogram_entropy(p, w, cfg.entropy_bin_xy_m, cfg.entropy_bin_theta_rad, "numpy")
    if c_fits:
        threshold = _threshold(mass, held, cfg.cluster_min_bin_frac, cfg.cluster_min_bin_frac > 0)
        sums = _k.summary_clusters(mass, count, threshold, ny, nx, c_nt, cell, pc, sin_th, cos_th, wc)
    else:  # absurdly spread cloud: the coarser raster, as the reference
        labels, n_lab = _cluster_labels_numba(pc, cfg.cluster_bin_m * 4.0, cfg.cluster_bin_theta_rad, w,
                                              cfg.cluster_min_bin_frac)  # fmt: skip
        sums = _k.cluster_sums(labels, n_lab, pc, sin_th, cos_th, wc)
    ccount, cw, wsum, csums, order, starts = sums
    cmean = _cluster_means(csums, wsum)
    ccov, keep = _k.summary_covariances(order, starts, pc, wc, ccount, cw, wsum, cmean, float(cfg.cluster_min_weight))
    mean, ess = np.array([mx, my, mth]), float(1.0 / np.sum(w * w))
    return mean, 0.5 * (cov + cov.T), ess, entropy, cw, cmean, ccov, ccount, keep.tolist()
