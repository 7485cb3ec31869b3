"""EKF-SLAM for 2D point landmarks with range-bearing observations (the baseline of paper 000).

One joint Gaussian over ``[x, y, theta, l1x, l1y, ..., lMx, lMy]`` (m, rad), as in
Bailey's ``ekfslam_v1``: the pose block is predicted with the motion model's
Jacobians at every control step; each observation is associated (ML with gates,
or known ids), then applied as a sequential EKF update or appended as a new
landmark (augmentation with the inverse observation model's Jacobians).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from filters.motion.velocity import MotionModel
from filters.pose import wrap_angle
from filters.slam.association import AssociationConfig, innovation, inv2, ml_scores, nis_and_logdet
from filters.slam.fastslam import SLAMEstimate
from filters.slam.landmarks import (
    RangeBearingNoise,
    check_finite_motion,
    checked_control,
    checked_pose_cov,
    inverse_observation,
    observation_jacobians,
    validate_observations,
)


@dataclass(frozen=True)
class EKFSLAMConfig:
    """Settings of `EKFSLAM`: the association mode and gates (`AssociationConfig`)."""

    association: AssociationConfig = field(default_factory=AssociationConfig)


class EKFSLAM:
    """Extended Kalman filter SLAM.

    ``predict(u, dt)`` at every control step, ``update(z, ids)`` at every scan (``z`` ``(K, 2)``
    rows ``(range_m, bearing_rad)``; empty or ``None`` = nothing to do), ``estimate()`` for the belief.
    Deterministic: it draws no random numbers. Bad observations raise ValueError.

    Attributes: ``x`` state ``(3 + 2M,)``, ``P`` covariance ``(3 + 2M, 3 + 2M)``, ``ids`` ``(M,)``
    landmark ids (known ids, or creation order under ML association).
    """

    def __init__(
        self,
        motion: MotionModel,
        obs_noise: RangeBearingNoise,
        config: EKFSLAMConfig | None = None,
        initial_pose=(0.0, 0.0, 0.0),
        initial_pose_cov=None,
    ) -> None:
        if config is not None and not isinstance(config, EKFSLAMConfig):
            raise TypeError(f"config must be an EKFSLAMConfig or None, got {type(config).__name__} {config!r:.60}")
        if not isinstance(obs_noise, RangeBearingNoise):
            raise TypeError(f"obs_noise must be a RangeBearingNoise, got {type(obs_noise).__name__} {obs_noise!r:.60}")
        self.motion = motion
        self.R = obs_noise.cov
        self.config = config if config is not None else EKFSLAMConfig()
        pose0 = np.asarray(initial_pose, dtype=np.float64)
        if pose0.shape != (3,) or not np.all(np.isfinite(pose0)):
            raise ValueError(f"initial_pose must be a finite (3,) array, got {initial_pose!r}")
        self.x = pose0.copy()
        self.x[2] = wrap_angle(self.x[2])
        self.P = np.zeros((3, 3)) if initial_pose_cov is None else checked_pose_cov(initial_pose_cov)
        self.ids = np.zeros(0, dtype=np.int64)
        self._slot_of: dict[int, int] = {}

    @property
    def n_landmarks(self) -> int:
        return (self.x.size - 3) // 2

    def predict(self, u, dt: float) -> None:
        """Propagate the pose by control ``u`` over ``dt`` seconds; landmarks are static."""
        u, dt = checked_control(u, dt)
        pose = self.x[None, :3]
        with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below, by name
            fx, fu = self.motion.jacobians(pose, u, dt)
            fx, fu = fx[0], fu[0]
            new = self.motion.mean(pose, u, dt)[0]
        check_finite_motion(u, dt, "pose", new, fx, fu)
        self.x[:3] = new
        P = self.P
        P[:3, :3] = fx @ P[:3, :3] @ fx.T + fu @ self.motion.control_cov @ fu.T
        if P.shape[0] > 3:
            P[:3, 3:] = fx @ P[:3, 3:]
            P[3:, :3] = P[:3, 3:].T

    def update(self, z=None, ids=None) -> None:
        """Incorporate one scan; each observation in turn is matched, applied, or added as a landmark."""
        z, ids = validate_observations(z, ids)
        mode = self.config.association.mode
        if mode == "known" and ids is None and z.shape[0] > 0:
            raise ValueError("known association needs landmark ids with every scan")
        for k in range(z.shape[0]):
            if mode == "known":
                slot = self._slot_of.get(int(ids[k]))
                if slot is None:
                    self._augment(z[k], int(ids[k]))
                else:
                    self._correct(z[k], slot)
            else:
                slot, is_new = self._associate_ml(z[k])
                if slot is not None:
                    self._correct(z[k], slot)
                elif is_new:
                    self._augment(z[k], self.n_landmarks)

    def step(self, u, dt: float, z=None, ids=None) -> None:
        """``predict(u, dt)`` then ``update(z, ids)``."""
        self.predict(u, dt)
        self.update(z, ids)

    def estimate(self) -> SLAMEstimate:
        """Pose mean and covariance, landmark means ``(M, 2)``, their 2x2 marginal covariances and ids."""
        m = self.n_landmarks
        idx = 3 + 2 * np.arange(m)
        covs = np.empty((m, 2, 2))
        covs[:, 0, 0] = self.P[idx, idx]
        covs[:, 0, 1] = self.P[idx, idx + 1]
        covs[:, 1, 0] = self.P[idx + 1, idx]
        covs[:, 1, 1] = self.P[idx + 1, idx + 1]
        return SLAMEstimate(
            self.x[:3].copy(), self.P[:3, :3].copy(), self.x[3:].reshape(m, 2).copy(), covs, self.ids.copy()
        )

    # ------------------------------------------------------------------ internals
    def _innovation_covs(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Predicted observations, Jacobians and innovation covariances of every landmark (vectorised)."""
        m = self.n_landmarks
        lms = self.x[3:].reshape(m, 2)
        z_hat, h_x, h_l = observation_jacobians(self.x[None, :3], lms)
        idx = 3 + 2 * np.arange(m)
        p_vv = self.P[:3, :3]
        p_vl = np.stack([self.P[:3, idx], self.P[:3, idx + 1]], axis=-1).transpose(1, 0, 2)  # (M, 3, 2)
        p_ll = np.empty((m, 2, 2))
        p_ll[:, 0, 0] = self.P[idx, idx]
        p_ll[:, 0, 1] = self.P[idx, idx + 1]
        p_ll[:, 1, 0] = self.P[idx + 1, idx]
        p_ll[:, 1, 1] = self.P[idx + 1, idx + 1]
        cross = h_x @ p_vl @ np.swapaxes(h_l, 1, 2)
        s = h_x @ p_vv @ np.swapaxes(h_x, 1, 2) + cross + np.swapaxes(cross, 1, 2)
        s = s + h_l @ p_ll @ np.swapaxes(h_l, 1, 2) + self.R
        return z_hat, h_x, h_l, s

    def _associate_ml(self, z: np.ndarray) -> tuple[int | None, bool]:
        """``(slot, False)`` for a match, ``(None, True)`` for a new landmark, ``(None, False)`` to ignore."""
        if self.n_landmarks == 0:
            return None, True
        gate = self.config.association
        z_hat, _, _, s = self._innovation_covs()
        nis, logdet = nis_and_logdet(innovation(z[None, :], z_hat), s)
        best = int(np.argmin(ml_scores(nis, logdet, gate)))
        if nis[best] < gate.gate_associate:
            return best, False
        return None, bool(nis.min() > gate.gate_new)

    def _correct(self, z: np.ndarray, slot: int) -> None:
        j = 3 + 2 * slot
        cols = np.array([0, 1, 2, j, j + 1])
        z_hat, h_x, h_l = observation_jacobians(self.x[:3], self.x[j : j + 2])
        h = np.concatenate([h_x, h_l], axis=1)  # (2, 5)
        pht = self.P[:, cols] @ h.T  # (n, 2)
        s = h @ pht[cols] + self.R
        s_inv, _ = inv2(s)
        gain = pht @ s_inv
        v = innovation(z, z_hat)
        self.x = self.x + gain @ v
        self.x[2] = wrap_angle(self.x[2])
        P = self.P - gain @ s @ gain.T
        self.P = 0.5 * (P + P.T)

    def _augment(self, z: np.ndarray, landmark_id: int) -> None:
        lm, g_x, g_z = inverse_observation(self.x[:3], z)
        n = self.x.size
        p_lx = g_x @ self.P[:3, :]  # (2, n)
        p_ll = g_x @ self.P[:3, :3] @ g_x.T + g_z @ self.R @ g_z.T
        P = np.zeros((n + 2, n + 2))
        P[:n, :n] = self.P
        P[n:, :n] = p_lx
        P[:n, n:] = p_lx.T
        P[n:, n:] = p_ll
        self.P = P
        self.x = np.concatenate([self.x, lm])
        self._slot_of[landmark_id] = self.n_landmarks - 1
        self.ids = np.append(self.ids, landmark_id)
