"""FA-FastSLAM and IFA-FastSLAM (paper 001, section 3): FastSLAM with a firefly move of the particle poses.

Both subclass `filters.slam.fastslam.FastSLAM` and use its hooks:

* ``_move_particles(z, assoc)`` (after pose sampling, before weighting): one firefly generation on
  the poses ``(N, 3)`` (`filters.smc.firefly.firefly_move`). In FastSLAM 1.0 (the setting of the
  reproduction) the moved poses are the ones weighted and used for the landmark EKF updates; in
  FastSLAM 2.0 a move changes the pose but not the weight (see the FastSLAM docstring).
* ``_resample(psi)`` / ``_mutate(mask)``: IFA-FastSLAM replaces systematic resampling by the
  step-wise EWA scheme (`filters.smc.firefly.ewa_resample`) and mutates the filler copies'
  poses with ``x' = x + x * mu * N(0, 1)`` (Eq. 8; relative to the coordinates, so origin-dependent,
  as the paper writes it), heading re-wrapped.

Brightness of particle ``i`` (paper: "predicted landmark value vs newest landmark observation,
predicted pose vs newest pose"):

* observation distance ``d_z``: Euclidean norm of the stacked innovations ``z_k - h(pose_i, m_ik)`` of
  the observations the particle *associates* with a landmark already in its map, each component
  divided by its noise standard deviation (range / ``sigma_r``, bearing / ``sigma_b``), so ``R = 1``.
  An observation the particle does not match but another particle does adds the association gate
  ``gate_associate`` to ``d_z^2``, the least it could add: its normalised innovation squared against the
  particle's nearest landmark is at least the gate, and the ``R``-normalised square is at least that (the
  innovation covariance exceeds ``R``). Without this, a particle that matches nothing would be the brightest of
  all. An observation no particle matches (a new landmark for all, as every one under known association) does
  not count. With no matched observation there is no move.
* state distance ``d_x`` (IFA only): distance of the predicted pose to the filter's *own* previous
  estimate (weighted-mean pose after the last update) pushed through the noise-free motion model with
  the controls since, each component divided by the predicted cloud's standard deviation, so ``Q = 1``.
  Never the true pose.

FA-FastSLAM: ``log I = -d_z^2 / 2``, fixed step. IFA-FastSLAM: **reconstructed** Eq. 2
``log I = -(d_z^2 + d_x^2) / 2`` and **reconstructed** Eq. 3 adaptive step. The random step is
``alpha0 * (sigma_r, sigma_r, sigma_b)`` (m, m, rad) times the step factor: the observation noise
scales it (Eq. 3's "noise of the observation process"). Attraction ``beta0 exp(-gamma r^2)`` uses
``r^2 = dx^2 + dy^2 + dtheta^2`` (m^2 and rad^2 mixed; headings are unwrapped around the cloud's
circular mean first). Brightness and step rule are constructor parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from filters.motion.velocity import MotionModel
from filters.pose import wrap_angle
from filters.slam.association import innovation
from filters.slam.fastslam import Association, FastSLAM, FastSLAMConfig
from filters.slam.landmarks import RangeBearingNoise, predict_observation
from filters.smc.firefly import (
    LogBrightnessFn,
    StepFactorFn,
    adaptive_step,
    apply_mutation,
    check_firefly_settings,
    ewa_resample,
    firefly_move,
    fixed_step,
    gaussian_log_brightness,
    observation_log_brightness,
)


@dataclass(frozen=True)
class FireflySLAMConfig:
    """Firefly settings of `FireflyFastSLAM`.

    alpha0: random step in units of the observation noise, ``alpha0 * (sigma_r, sigma_r, sigma_b)``.
    beta0, gamma: attraction at zero distance and absorption (1/m^2; paper 1, 1).
    move_mode, pairwise_max_n: see `filters.smc.firefly.firefly_move`.
    use_ewa: EWA step-wise resampling + pose mutation instead of ``FastSLAMConfig.resampler``.
    ewa_beta, mutation_mu: paper 0.8 and 0.01.
    """

    alpha0: float = 1.0
    beta0: float = 1.0
    gamma: float = 1.0
    move_mode: str = "auto"
    pairwise_max_n: int = 200
    use_ewa: bool = False
    ewa_beta: float = 0.8
    mutation_mu: float = 0.01

    def __post_init__(self) -> None:
        check_firefly_settings(self)


class FireflyFastSLAM(FastSLAM):
    """FastSLAM with a firefly pose move before weighting (see the module docstring).

    Same usage as `FastSLAM` (``predict``, ``update``, ``estimate``); extra arguments:
    ``firefly`` settings, ``log_brightness`` (`filters.smc.firefly.LogBrightnessFn`, called with
    noise-normalised distances and unit variances) and ``step_factor`` (`filters.smc.firefly.StepFactorFn`).
    """

    def __init__(
        self,
        motion: MotionModel,
        obs_noise: RangeBearingNoise,
        config: FastSLAMConfig,
        rng: np.random.Generator,
        initial_pose=(0.0, 0.0, 0.0),
        initial_pose_cov=None,
        firefly: FireflySLAMConfig | None = None,
        log_brightness: LogBrightnessFn = observation_log_brightness,
        step_factor: StepFactorFn = fixed_step,
    ) -> None:
        super().__init__(motion, obs_noise, config, rng, initial_pose, initial_pose_cov)
        self.firefly = firefly if firefly is not None else FireflySLAMConfig()
        self.log_brightness = log_brightness
        self.step_factor = step_factor
        self._ref_pose = self._mean_pose()
        self.n_moves = 0

    # ---- the filter's own reference pose ---------------------------------------------------
    def _mean_pose(self) -> np.ndarray:
        w = np.exp(self.log_weights)
        th = np.arctan2(w @ np.sin(self.poses[:, 2]), w @ np.cos(self.poses[:, 2]))
        return np.array([w @ self.poses[:, 0], w @ self.poses[:, 1], float(wrap_angle(th))])

    def predict(self, u, dt: float) -> None:
        super().predict(u, dt)
        ref = self.motion.mean(self._ref_pose[None, :], np.asarray(u, dtype=np.float64), dt)[0]
        ref[2] = wrap_angle(ref[2])
        self._ref_pose = ref

    def update(self, z=None, ids=None) -> None:
        before = self.n_updates
        super().update(z, ids)
        if self.n_updates > before:
            self._ref_pose = self._mean_pose()

    # ---- hooks -------------------------------------------------------------------------------
    def _distances(self, z: np.ndarray, assoc: Association) -> tuple[np.ndarray, np.ndarray, bool]:
        """Noise-normalised observation and state distances ``(N,)``, and whether any observation matched."""
        n = self.n_particles
        rows = np.arange(n)
        sig = np.array([self.obs_noise.sigma_r_m, self.obs_noise.sigma_b_rad])
        matched = assoc.matched
        missed = ~matched & matched.any(axis=0)[None, :]  # matched by other particles, not by this one
        d2 = self.config.association.gate_associate * np.count_nonzero(missed, axis=1)
        for j in range(z.shape[0]):
            sel = rows[assoc.matched[:, j]]
            if sel.size == 0:
                continue
            z_hat = predict_observation(self.poses[sel], self.lm_mean[sel, assoc.slots[sel, j]])
            v = innovation(z[j][None, :], z_hat) / sig
            d2[sel] += np.sum(v * v, axis=1)
        diff = self.poses - self._ref_pose[None, :]
        diff[:, 2] = wrap_angle(diff[:, 2])
        w = np.exp(self.log_weights)
        centred = diff - w @ diff
        q = np.maximum(w @ (centred * centred), 1e-12)
        return np.sqrt(d2), np.sqrt(np.sum(diff * diff / q, axis=1)), bool(assoc.matched.any())

    def _move_particles(self, z: np.ndarray, assoc: Association) -> None:
        obs_dist, state_dist, any_match = self._distances(z, assoc)
        if not any_match:
            return
        cfg = self.firefly
        log_i = self.log_brightness(obs_dist, state_dist, 1.0, 1.0)
        poses = self.poses.copy()
        th0 = self._mean_pose()[2]
        poses[:, 2] = th0 + wrap_angle(poses[:, 2] - th0)
        alpha0 = cfg.alpha0 * np.array([self.obs_noise.sigma_r_m, self.obs_noise.sigma_r_m, self.obs_noise.sigma_b_rad])
        moved = firefly_move(
            poses,
            log_i,
            alpha0,
            self.rng,
            step_factor=self.step_factor,
            beta0=cfg.beta0,
            gamma=cfg.gamma,
            mode=cfg.move_mode,
            pairwise_max_n=cfg.pairwise_max_n,
        )
        moved[:, 2] = wrap_angle(moved[:, 2])
        self.poses = moved
        self.n_moves += 1

    def _resample(self, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        if not self.firefly.use_ewa:
            return super()._resample(psi)
        return ewa_resample(psi, self.firefly.ewa_beta)

    def _mutate(self, mask: np.ndarray) -> None:
        k = int(mask.sum())
        p = apply_mutation(self.poses[mask], np.arange(k), np.ones(k, dtype=bool), self.firefly.mutation_mu, self.rng)
        p[:, 2] = wrap_angle(p[:, 2])
        self.poses[mask] = p


class FAFastSLAM(FireflyFastSLAM):
    """FA-FastSLAM: observation brightness, fixed step, the configured standard resampler."""

    def __init__(
        self,
        motion,
        obs_noise,
        config,
        rng,
        initial_pose=(0.0, 0.0, 0.0),
        initial_pose_cov=None,
        firefly: FireflySLAMConfig | None = None,
    ) -> None:
        super().__init__(
            motion,
            obs_noise,
            config,
            rng,
            initial_pose,
            initial_pose_cov,
            firefly if firefly is not None else FireflySLAMConfig(use_ewa=False),
            observation_log_brightness,
            fixed_step,
        )


class IFAFastSLAM(FireflyFastSLAM):
    """IFA-FastSLAM (paper 001): reconstructed Eq. 2 brightness with the state term, adaptive step, EWA resampling."""

    def __init__(
        self,
        motion,
        obs_noise,
        config,
        rng,
        initial_pose=(0.0, 0.0, 0.0),
        initial_pose_cov=None,
        firefly: FireflySLAMConfig | None = None,
        log_brightness: LogBrightnessFn = gaussian_log_brightness,
        step_factor: StepFactorFn = adaptive_step,
    ) -> None:
        super().__init__(
            motion,
            obs_noise,
            config,
            rng,
            initial_pose,
            initial_pose_cov,
            firefly if firefly is not None else FireflySLAMConfig(use_ewa=True),
            log_brightness,
            step_factor,
        )
