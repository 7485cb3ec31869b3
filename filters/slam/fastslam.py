"""FastSLAM 1.0 and 2.0 for 2D point landmarks and range-bearing observations, vectorised over particles.

Each particle holds a pose and a map of independent landmark Gaussians (mean,
2x2 covariance), EKF-updated when observed (Montemerlo et al. 2002/2003;
paper 000 Eq. 9-11). State arrays, ``N`` particles, capacity ``C`` landmark slots:

=================  ================  =================================================
``poses``          ``(N, 3)``        x (m), y (m), theta (rad, in [-pi, pi))
``pose_cov``       ``(N, 3, 3)``     FastSLAM 2.0 only: predicted pose covariance since the last update
``lm_mean``        ``(N, C, 2)``     landmark means (m)
``lm_cov``         ``(N, C, 2, 2)``  landmark covariances (m^2)
``exists``         ``(N, C)`` bool   slot holds a landmark
``count``          ``(N,)`` int      landmarks per particle
``log_weights``    ``(N,)``          normalised log weights (log-sum-exp = 0)
=================  ================  =================================================

With known association slot ``j`` is landmark id ``j`` (so ids should be small integers: the
arrays get ``max id + 1`` slots); with ML association each particle fills its slots in the
order it creates landmarks. Capacity grows as needed.

The weight step can be transformed before resampling (`filters.slam.weight_transforms`;
paper 000's WOC is ``weight_transform=WOC(K)``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.special import logsumexp

from filters.motion.velocity import MotionModel
from filters.numbers import is_int
from filters.pose import wrap_angle
from filters.slam.association import AssociationConfig, gauss_logpdf, innovation, inv2, ml_scores, nis_and_logdet
from filters.slam.landmarks import (
    RangeBearingNoise,
    check_finite_motion,
    checked_control,
    checked_pose_cov,
    inverse_observation,
    observation_jacobians,
    validate_observations,
)
from filters.slam.weight_transforms import identity
from filters.smc.resampling import effective_sample_size, get_resampler

MAX_KNOWN_ID = 100_000
"""Largest landmark id known association takes: ids index every particle's landmark slots."""


@dataclass(frozen=True)
class FastSLAMConfig:
    """Settings of `FastSLAM`.

    n_particles: number of particles ``N >= 1``.
    version: 1 (sample the motion model; weight = observation likelihood) or 2 (Gaussian proposal
        refined by the observations, weight = marginal likelihood; Montemerlo 2003).
    association: `AssociationConfig` (ML with gates, or known ids).
    resampler: name for `filters.smc.resampling.get_resampler` (default systematic).
    resample_ess_fraction: resample when ESS of the transformed weights ``< fraction * N``;
        ``1.0`` (default) resamples after every update with observations, as both papers do.
    weight_transform: callable ``weights -> weights`` applied before resampling
        (`identity` or `WOC`).
    initial_capacity: landmark slots allocated up front (grows on demand).
    """

    n_particles: int = 100
    version: int = 2
    association: AssociationConfig = field(default_factory=AssociationConfig)
    resampler: str = "systematic"
    resample_ess_fraction: float = 1.0
    weight_transform: Callable[[np.ndarray], np.ndarray] = identity
    initial_capacity: int = 16

    def __post_init__(self) -> None:
        if not is_int(self.n_particles) or self.n_particles < 1:
            raise ValueError(f"n_particles must be a positive integer, got {self.n_particles!r}")
        if not is_int(self.version) or self.version not in (1, 2):
            raise ValueError(f"version must be 1 or 2, got {self.version!r}")
        if not 0.0 < self.resample_ess_fraction <= 1.0:
            raise ValueError(f"resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction}")
        if not is_int(self.initial_capacity) or self.initial_capacity < 1:
            raise ValueError(f"initial_capacity must be an integer >= 1, got {self.initial_capacity!r}")
        get_resampler(self.resampler)  # unknown name -> ValueError now, not mid-run
        if not callable(self.weight_transform):  # checked now: the first update would fail after changing the state
            raise TypeError(
                f"weight_transform must be a callable weights -> weights (identity, WOC(k)), "
                f"got {self.weight_transform!r}"
            )


@dataclass(frozen=True)
class Association:
    """Per-particle association of one scan of ``K`` observations.

    slots ``(N, K)`` int: landmark slot each observation refers to (meaningful where matched or new).
    matched ``(N, K)`` bool: observation updates an existing landmark.
    new ``(N, K)`` bool: observation creates a landmark in ``slots``.
    Neither matched nor new: the observation is ignored by that particle (ambiguous gate zone).
    """

    slots: np.ndarray
    matched: np.ndarray
    new: np.ndarray


@dataclass(frozen=True)
class SLAMEstimate:
    """A filter's belief summary.

    pose ``(3,)`` (m, m, rad) and pose_cov ``(3, 3)``; landmarks ``(M, 2)`` (m), landmark_covs
    ``(M, 2, 2)`` (m^2) and landmark_ids ``(M,)`` (the known id, or the slot index under ML association).
    """

    pose: np.ndarray
    pose_cov: np.ndarray
    landmarks: np.ndarray
    landmark_covs: np.ndarray
    landmark_ids: np.ndarray

    @property
    def count(self) -> int:
        return int(self.landmarks.shape[0])


def _sample_gaussians(mean: np.ndarray, cov: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw from each ``N(mean_i, cov_i)``, ``mean (n, d)``, ``cov (n, d, d)`` (PSD; eigen square root)."""
    cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    vals, vecs = np.linalg.eigh(cov)
    root = vecs * np.sqrt(np.clip(vals, 0.0, None))[..., None, :]
    return mean + np.einsum("nij,nj->ni", root, rng.standard_normal(mean.shape))


class FastSLAM:
    """FastSLAM 1.0 / 2.0 with pluggable motion model, association, weight transform and resampler.

    Usage: ``predict(u, dt)`` at every control step, ``update(z, ids)`` at every scan
    (``z`` ``(K, 2)`` rows ``(range_m, bearing_rad)``; ``K = 0`` or ``None`` is a predict-only step),
    ``estimate()`` for the belief. All randomness comes from the ``rng`` given to the constructor.

    Per-update algorithm and its overridable hooks (in call order)::

        z, ids = validate_observations(z, ids)          # ValueError on bad input
        assoc  = self._associate(z, ids)                # -> Association (N, K)
        dlogw  = self._propose(z, assoc)                # sample poses; v2: Gaussian proposal + marginal lik.
        self._move_particles(z, assoc)                  # HOOK: identity; poses may be changed in place here
        dlogw += self._weigh_and_update_maps(z, assoc)  # v1: obs likelihood; both: clutter/new terms; EKF maps
        self.log_weights = normalise(self.log_weights + dlogw)     # log-sum-exp
        psi = self._transform_weights(w)                # HOOK: config.weight_transform (identity / WOC)
        if self._should_resample(psi):                  # ESS rule
            indices, mutate = self._resample(psi)       # HOOK: -> (N,) ancestors, (N,) bool mask or None
            self._apply_resample(indices, mutate)       # copies rows; calls self._mutate(mutate) if any True
                                                        # HOOK _mutate(mask): identity; e.g. jitter copies

    Notes for subclasses (e.g. IFA-FastSLAM): ``_move_particles`` runs after pose sampling and
    before weighting, so in version 1 the moved poses are the ones weighted and used for the map
    update. In version 2 the proposal's marginal likelihood is computed in ``_propose`` before the
    hook; a move then changes the pose the map update uses but not the weight. ``_resample`` may
    return any ``N`` ancestor indices (not necessarily sorted) and a mask of rows to mutate.
    After resampling the weights are uniform.
    """

    def __init__(
        self,
        motion: MotionModel,
        obs_noise: RangeBearingNoise,
        config: FastSLAMConfig,
        rng: np.random.Generator,
        initial_pose=(0.0, 0.0, 0.0),
        initial_pose_cov=None,
    ) -> None:
        if not isinstance(config, FastSLAMConfig):
            raise TypeError(f"config must be a FastSLAMConfig, got {type(config).__name__} {config!r:.60}")
        if not isinstance(obs_noise, RangeBearingNoise):
            raise TypeError(f"obs_noise must be a RangeBearingNoise, got {type(obs_noise).__name__} {obs_noise!r:.60}")
        self.motion = motion
        self.obs_noise = obs_noise
        self.R = obs_noise.cov
        self.config = config
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        self.rng = rng
        self._resampler = get_resampler(config.resampler)
        n, c = config.n_particles, config.initial_capacity
        pose0 = np.asarray(initial_pose, dtype=np.float64)
        if pose0.shape != (3,) or not np.all(np.isfinite(pose0)):
            raise ValueError(f"initial_pose must be a finite (3,) array, got {initial_pose!r}")
        self.poses = np.tile(pose0, (n, 1))
        self.pose_cov = np.zeros((n, 3, 3))
        if initial_pose_cov is not None:
            p0 = checked_pose_cov(initial_pose_cov)
            if config.version == 2:
                self.pose_cov[:] = p0
            else:
                self.poses = _sample_gaussians(self.poses, np.broadcast_to(p0, (n, 3, 3)), rng)
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        self.lm_mean = np.zeros((n, c, 2))
        self.lm_cov = np.zeros((n, c, 2, 2))
        self.exists = np.zeros((n, c), dtype=bool)
        self.count = np.zeros(n, dtype=np.int64)
        self.log_weights = np.full(n, -np.log(n))
        self.last_weights = np.full(n, 1.0 / n)  # normalised weights of the last update, before resampling
        self._best = 0
        self.n_updates = 0
        self.n_resamples = 0
        # log-likelihood given to an observation a particle does not match (new landmark or ignored):
        # a match lying exactly on the new-landmark gate with innovation covariance R.
        self._log_p0 = -0.5 * config.association.gate_new - 0.5 * np.log(np.linalg.det(self.R)) - np.log(2 * np.pi)

    # ------------------------------------------------------------------ public API
    @property
    def n_particles(self) -> int:
        return self.poses.shape[0]

    @property
    def weights(self) -> np.ndarray:
        """Current normalised weights ``(N,)``."""
        return np.exp(self.log_weights)

    def predict(self, u, dt: float) -> None:
        """Move every particle by control ``u`` (model units) over ``dt`` seconds."""
        u, dt = checked_control(u, dt)
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below, by name
            if self.config.version == 1:
                poses = self.motion.sample(self.poses, u, dt, self.rng)
                cov = self.pose_cov
            else:
                fx, fu = self.motion.jacobians(self.poses, u, dt)
                q = self.motion.control_cov
                cov = fx @ self.pose_cov @ np.swapaxes(fx, 1, 2) + fu @ q @ np.swapaxes(fu, 1, 2)
                poses = self.motion.mean(self.poses, u, dt)
        check_finite_motion(u, dt, "poses", poses, cov)
        self.poses, self.pose_cov = poses, cov

    def update(self, z=None, ids=None) -> None:
        """Incorporate one scan ``z (K, 2)`` (range m, bearing rad); ``ids (K,)`` for known association."""
        z, ids = validate_observations(z, ids)
        if self.config.association.mode == "known" and ids is None and z.shape[0] > 0:
            raise ValueError("known association needs landmark ids with every scan")
        if self.config.association.mode == "known" and ids is not None and ids.size and ids.max() > MAX_KNOWN_ID:
            raise ValueError(  # known ids index every particle's landmark arrays
                f"known-association landmark ids must be at most {MAX_KNOWN_ID:,} (they index map slots of every "
                f"particle), got {int(ids.max())}"
            )
        if z.shape[0] == 0:
            return
        self.n_updates += 1
        assoc = self._associate(z, ids)
        dlogw = self._propose(z, assoc)
        self._move_particles(z, assoc)
        dlogw = dlogw + self._weigh_and_update_maps(z, assoc)
        lw = self.log_weights + dlogw
        lw = np.where(np.isfinite(lw), lw, -np.inf)
        if not np.any(np.isfinite(lw)):
            lw = np.zeros_like(lw)  # every particle impossible: fall back to uniform rather than NaN
        self.log_weights = lw - logsumexp(lw)
        w = np.exp(self.log_weights)
        self.last_weights = w
        self._best = int(np.argmax(w))
        psi = self._transform_weights(w)
        if self._should_resample(psi):
            indices, mutate = self._resample(psi)
            self._apply_resample(indices, mutate)

    def step(self, u, dt: float, z=None, ids=None) -> None:
        """``predict(u, dt)`` then ``update(z, ids)``."""
        self.predict(u, dt)
        self.update(z, ids)

    def estimate(self) -> SLAMEstimate:
        """Weighted-mean pose (circular mean for theta), its covariance, and the best particle's map.

        In version 2 the covariance adds the mean of the particles' predicted pose covariances.
        """
        w = np.exp(self.log_weights)
        x = w @ self.poses[:, 0]
        y = w @ self.poses[:, 1]
        th = float(np.arctan2(w @ np.sin(self.poses[:, 2]), w @ np.cos(self.poses[:, 2])))
        mean = np.array([x, y, wrap_angle(th)])
        d = self.poses - mean
        d[:, 2] = wrap_angle(d[:, 2])
        cov = (d * w[:, None]).T @ d + np.einsum("n,nij->ij", w, self.pose_cov)
        b = self._best
        slots = np.flatnonzero(self.exists[b])
        return SLAMEstimate(mean, cov, self.lm_mean[b, slots].copy(), self.lm_cov[b, slots].copy(), slots)

    # ------------------------------------------------------------------ hooks
    def _associate(self, z: np.ndarray, ids: np.ndarray | None) -> Association:
        """Associate each observation with a landmark slot, per particle (vectorised)."""
        n, k = self.n_particles, z.shape[0]
        if self.config.association.mode == "known":
            self._ensure_capacity(int(ids.max()) + 1)
            slots = np.broadcast_to(ids, (n, k)).copy()
            matched = self.exists[:, ids]
            new = ~matched
            # a repeated unseen id within one scan: only the first creates it, the rest update it
            if k > 1 and np.unique(ids).size < k:
                for j in range(1, k):
                    earlier = ids[:j] == ids[j]
                    if np.any(earlier):
                        new[:, j] = False
                        matched[:, j] = True
            return Association(slots, matched, new)
        gate = self.config.association
        slots = np.zeros((n, k), dtype=np.int64)
        matched = np.zeros((n, k), dtype=bool)
        new = np.ones((n, k), dtype=bool)
        used = int(self.count.max())  # ML fills slots in order: slots >= used are empty in every particle
        if used > 0:
            exists = self.exists[:, :used]
            z_hat, h_x, h_l = observation_jacobians(self.poses[:, None, :], self.lm_mean[:, :used])  # (N, C, ...)
            s = h_l @ self.lm_cov[:, :used] @ np.swapaxes(h_l, -1, -2) + self.R
            if self.config.version == 2:
                s = s + h_x @ self.pose_cov[:, None] @ np.swapaxes(h_x, -1, -2)
            s = np.where(exists[..., None, None], s, np.eye(2))
            v = innovation(z[None, None, :, :], z_hat[:, :, None, :])  # (N, C, K, 2)
            nis, logdet = nis_and_logdet(v, s[:, :, None])
            nis = np.where(exists[:, :, None], nis, np.inf)
            best = np.argmin(ml_scores(nis, logdet, gate), axis=1)  # (N, K)
            best_nis = np.take_along_axis(nis, best[:, None, :], axis=1)[:, 0, :]
            min_nis = nis.min(axis=1)
            slots = best
            matched = best_nis < gate.gate_associate
            new = (min_nis > gate.gate_new) & ~matched
        n_new = new.sum(axis=1)
        if n_new.any():
            self._ensure_capacity(int((self.count + n_new).max()))
            new_slots = self.count[:, None] + np.cumsum(new, axis=1) - 1
            slots = np.where(new, new_slots, slots)
        return Association(slots, matched, new)

    def _propose(self, z: np.ndarray, assoc: Association) -> np.ndarray:
        """Draw the particles' poses for this update; return a log-weight increment ``(N,)``.

        Version 1: poses were sampled from the motion model in `predict`; returns zeros.
        Version 2: refine each particle's predicted Gaussian ``N(pose, pose_cov)`` with its
        matched observations (sequential EKF steps), accumulate the marginal log-likelihood
        ``log N(v; 0, H_x P H_x^T + H_l P_l H_l^T + R)``, sample a pose from the refined
        Gaussian and reset ``pose_cov`` to zero.
        """
        n = self.n_particles
        dlogw = np.zeros(n)
        if self.config.version == 1:
            return dlogw
        mean, cov = self.poses.copy(), self.pose_cov.copy()
        rows = np.arange(n)
        for j in range(z.shape[0]):
            # a landmark first seen in this scan (a repeated new id under known association: matched, to update
            # the landmark its first sighting makes) has no estimate yet to refine the pose with
            sel = rows[assoc.matched[:, j]]
            sel = sel[self.exists[sel, assoc.slots[sel, j]]]
            if sel.size == 0:
                continue
            sl = assoc.slots[sel, j]
            z_hat, h_x, h_l = observation_jacobians(mean[sel], self.lm_mean[sel, sl])
            p_l = self.lm_cov[sel, sl]
            p_x = cov[sel]
            s = h_l @ p_l @ np.swapaxes(h_l, 1, 2) + self.R + h_x @ p_x @ np.swapaxes(h_x, 1, 2)
            v = innovation(z[j][None, :], z_hat)
            dlogw[sel] += gauss_logpdf(v, s)
            s_inv, _ = inv2(s)
            gain = p_x @ np.swapaxes(h_x, 1, 2) @ s_inv  # (n, 3, 2)
            mean[sel] = mean[sel] + np.einsum("nij,nj->ni", gain, v)
            mean[sel, 2] = wrap_angle(mean[sel, 2])
            p_new = p_x - gain @ s @ np.swapaxes(gain, 1, 2)
            cov[sel] = 0.5 * (p_new + np.swapaxes(p_new, 1, 2))
        self.poses = _sample_gaussians(mean, cov, self.rng)
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        self.pose_cov = np.zeros_like(self.pose_cov)
        return dlogw

    def _move_particles(self, z: np.ndarray, assoc: Association) -> None:
        """Hook called after pose sampling, before weighting: may change ``self.poses`` in place. Identity."""

    def _weigh_and_update_maps(self, z: np.ndarray, assoc: Association) -> np.ndarray:
        """One pass over the observations: weight terms and landmark EKF updates / initialisations.

        Returns the log-weight increment ``(N,)``: in version 1 the log-likelihood
        ``log N(v; 0, H_l P_l H_l^T + R)`` of matched observations; in both versions a
        constant ``log p0`` for each observation a particle does not match.
        """
        n = self.n_particles
        rows = np.arange(n)
        dlogw = np.zeros(n)
        for j in range(z.shape[0]):
            dlogw[~assoc.matched[:, j]] += self._log_p0
            sel = rows[assoc.matched[:, j]]
            if sel.size:
                sl = assoc.slots[sel, j]
                z_hat, _, h_l = observation_jacobians(self.poses[sel], self.lm_mean[sel, sl])
                p_l = self.lm_cov[sel, sl]
                s = h_l @ p_l @ np.swapaxes(h_l, 1, 2) + self.R
                v = innovation(z[j][None, :], z_hat)
                if self.config.version == 1:
                    dlogw[sel] += gauss_logpdf(v, s)
                s_inv, _ = inv2(s)
                gain = p_l @ np.swapaxes(h_l, 1, 2) @ s_inv
                self.lm_mean[sel, sl] += np.einsum("nij,nj->ni", gain, v)
                p_new = p_l - gain @ s @ np.swapaxes(gain, 1, 2)
                self.lm_cov[sel, sl] = 0.5 * (p_new + np.swapaxes(p_new, 1, 2))
            sel = rows[assoc.new[:, j]]
            if sel.size:
                sl = assoc.slots[sel, j]
                lm, _, g_z = inverse_observation(self.poses[sel], z[j][None, :])
                self.lm_mean[sel, sl] = lm
                self.lm_cov[sel, sl] = g_z @ self.R @ np.swapaxes(g_z, 1, 2)
                self.exists[sel, sl] = True
        self.count = self.exists.sum(axis=1)
        return dlogw

    def _transform_weights(self, weights: np.ndarray) -> np.ndarray:
        """Hook: the resampling distribution from normalised weights (``config.weight_transform``)."""
        return self.config.weight_transform(weights)

    def _should_resample(self, psi: np.ndarray) -> bool:
        """Resample when ``config.resample_ess_fraction >= 1`` or ESS(psi) < fraction * N."""
        frac = self.config.resample_ess_fraction
        if frac >= 1.0:
            return True
        return effective_sample_size(psi) < frac * self.n_particles

    def _resample(self, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Hook: ``(indices (N,), mutate mask (N,) bool or None)``; default: the configured scheme, no mutation."""
        return self._resampler(psi, self.rng), None

    def _apply_resample(self, indices: np.ndarray, mutate: np.ndarray | None) -> None:
        """Copy every per-particle array along ``indices``, set uniform weights, then ``_mutate``."""
        indices = np.asarray(indices, dtype=np.int64)
        if indices.shape != (self.n_particles,):
            raise ValueError(f"resampling must return {self.n_particles} indices, got shape {indices.shape}")
        self._best = int(np.argmax(self.last_weights[indices]))
        self.poses = self.poses[indices]
        self.pose_cov = self.pose_cov[indices]
        self.lm_mean = self.lm_mean[indices]
        self.lm_cov = self.lm_cov[indices]
        self.exists = self.exists[indices]
        self.count = self.count[indices]
        self.log_weights = np.full(self.n_particles, -np.log(self.n_particles))
        self.n_resamples += 1
        if mutate is not None and np.any(mutate):
            self._mutate(np.asarray(mutate, dtype=bool))

    def _mutate(self, mask: np.ndarray) -> None:
        """Hook: perturb the rows in ``mask`` after resampling. Identity."""

    # ------------------------------------------------------------------ internals
    def _ensure_capacity(self, needed: int) -> None:
        c = self.exists.shape[1]
        if needed <= c:
            return
        extra = max(needed, 2 * c) - c
        n = self.n_particles
        self.lm_mean = np.concatenate([self.lm_mean, np.zeros((n, extra, 2))], axis=1)
        self.lm_cov = np.concatenate([self.lm_cov, np.zeros((n, extra, 2, 2))], axis=1)
        self.exists = np.concatenate([self.exists, np.zeros((n, extra), dtype=bool)], axis=1)
