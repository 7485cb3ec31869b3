"""Odometry-driven motion model for the SLAM filters: `filters.motion.odometry.OdometryMotionModel` behind
the `filters.motion.velocity.MotionModel` protocol.

The control is the odometry increment ``u = (dx m, dy m, dtheta rad)`` in the frame of the *previous*
robot pose (``filters.pose.relative(prev, now)``), as wheel odometry reports it; ``dt`` is accepted for
the protocol and ignored (the increment already covers one step). The increment is decomposed into
``(rot1, trans, rot2)`` exactly as `filters.motion.odometry.decompose` does::

    heading = theta + rot1
    x' = x + trans cos(heading);  y' = y + trans sin(heading);  theta' = wrap(heading + rot2)

Noise (Thrun et al., Table 5.6): ``rot1, trans, rot2`` are perturbed by independent zero-mean Gaussians
whose standard deviations ``(s_r1, s_t, s_r2)`` depend on the increment itself
(`filters.motion.odometry.OdometryMotionModel.stds`). The protocol's ``control_cov`` is a constant, so the
noise is written in *standardised* form: ``(rot1, trans, rot2) + diag(s_r1, s_t, s_r2) @ eps`` with
``eps ~ N(0, I_3)``. Hence

* ``control_cov`` is ``I_3`` (the covariance of ``eps``, dimensionless), and
* ``F_u`` returned by `jacobians` is the derivative of the mean wrt ``eps``:
  ``d mean / d(rot1, trans, rot2) @ diag(s_r1, s_t, s_r2)``, so ``F_u control_cov F_u^T`` is the
  first-order pose covariance of one odometry step -- what FastSLAM 2.0's predict needs.

Shapes differ from the car-like models of `filters.motion.velocity` (their controls and ``control_cov``
are 2D): here ``u`` is ``(3,)``, ``F_u`` is ``(N, 3, 3)`` and ``control_cov`` ``(3, 3)``. FastSLAM only
forms ``F_u Q F_u^T`` and passes ``u`` through, so it works unchanged.

`sample` delegates to `filters.motion.odometry.OdometryMotionModel.sample` (FastSLAM 1.0's predict),
so a particle filter and the simulator's odometry share one noise model.
"""

from __future__ import annotations

import numpy as np

from filters.motion.odometry import OdometryMotionConfig, OdometryMotionModel
from filters.pose import wrap_angle


def _increment(u) -> np.ndarray:
    u = np.asarray(u, dtype=np.float64)
    if u.shape != (3,) or not np.all(np.isfinite(u)):
        raise ValueError(f"odometry control must be a finite (3,) increment (dx m, dy m, dtheta rad), got {u!r}")
    return u


def _poses(poses) -> np.ndarray:
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim == 1:
        p = p.reshape(1, -1)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"poses must have shape (N, 3), got {np.shape(poses)}")
    return p


class OdometryIncrementModel:
    """Odometry increments as SLAM controls (see the module docstring for the contract).

    Args:
        config: noise alphas of the rot1-trans-rot2 model (`filters.motion.odometry.OdometryMotionConfig`);
            default the model's defaults. ``min_trans_m`` decides when ``rot1`` is taken as 0, and
            ``exact_small_moves`` whether a shorter step still moves in its own direction (`OdometryMotionConfig`).

    Stateless apart from the config; randomness only in `sample`, from the ``rng`` passed in.
    """

    def __init__(self, config: OdometryMotionConfig | None = None) -> None:
        self.config = config if config is not None else OdometryMotionConfig()
        self._model = OdometryMotionModel(self.config)

    @property
    def control_cov(self) -> np.ndarray:
        """``I_3``: the covariance of the standardised noise ``eps`` (the stds live in ``F_u``)."""
        return np.eye(3)

    def mean(self, poses, u, dt: float = 0.0) -> np.ndarray:
        """Noise-free next poses ``(N, 3)``, headings wrapped to ``[-pi, pi)``. ``dt`` is ignored."""
        p = _poses(poses)
        rot1, trans, rot2 = self._model.parts(_increment(u))[:3]
        heading = p[:, 2] + rot1
        out = np.empty_like(p)
        out[:, 0] = p[:, 0] + trans * np.cos(heading)
        out[:, 1] = p[:, 1] + trans * np.sin(heading)
        out[:, 2] = wrap_angle(heading + rot2)
        return out

    def jacobians(self, poses, u, dt: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """``(F_x (N, 3, 3), F_u (N, 3, 3))``: of `mean` wrt the pose and the standardised noise."""
        p = _poses(poses)
        delta = _increment(u)
        rot1, trans, _, s_r1, s_t, s_r2 = self._model.parts(delta)
        n = p.shape[0]
        heading = p[:, 2] + rot1
        c, s = np.cos(heading), np.sin(heading)
        fx = np.zeros((n, 3, 3))
        fx[:, 0, 0] = fx[:, 1, 1] = fx[:, 2, 2] = 1.0
        fx[:, 0, 2] = -trans * s
        fx[:, 1, 2] = trans * c
        fu = np.zeros((n, 3, 3))
        # columns: d/d rot1, d/d trans, d/d rot2, each times its noise std
        fu[:, 0, 0] = -trans * s * s_r1
        fu[:, 1, 0] = trans * c * s_r1
        fu[:, 2, 0] = s_r1
        fu[:, 0, 1] = c * s_t
        fu[:, 1, 1] = s * s_t
        fu[:, 2, 2] = s_r2
        return fx, fu

    def sample(self, poses, u, dt: float, rng: np.random.Generator) -> np.ndarray:
        """Next poses ``(N, 3)`` with independent noise per row (3 normal draws of size N from ``rng``)."""
        return self._model.sample(_poses(poses), _increment(u), rng)
