"""Univariate nonstationary growth model (UNGM), the benchmark of paper 001 (Eq. 9).

    x_t = 0.5 x_{t-1} + 25 x_{t-1} / (1 + x_{t-1}^2) + 8 cos(1.2 (t - 1)) + w_t,   w_t ~ N(0, Q)
    y_t = x_t^2 / 20 + v_t,                                                         v_t ~ N(0, R)

with ``Q = R = 1`` and ``x_0 = 0`` in the paper. Eq. 9 is an image lost from the
paper text; this is the standard form (Kitagawa 1996; Gordon et al. 1993) as the
project digest gives it, with the cosine argument ``1.2 (t - 1)``.
The state and observation are dimensionless scalars held as ``(N, 1)`` / ``(1,)``.
The observation depends on ``x^2`` only, so the posterior is often bimodal (+/- x).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class GrowthModelParams:
    """Parameters of `GrowthModel`.

    q_var: process noise variance ``Q``.  r_var: observation noise variance ``R``.
    x0: true initial state used by `GrowthModel.simulate`.
    init_var: variance of the filter prior ``x_0 ~ N(x0, init_var)`` (0 = known exactly).
    """

    q_var: float = 1.0
    r_var: float = 1.0
    x0: float = 0.0
    init_var: float = 1.0

    def __post_init__(self) -> None:
        values = (self.q_var, self.r_var, self.x0, self.init_var)
        if not (all(np.isfinite(values)) and self.q_var > 0 and self.r_var > 0 and self.init_var >= 0):
            raise ValueError(
                f"invalid growth model parameters: {self}; q_var and r_var must be finite and > 0, init_var finite "
                "and >= 0, x0 finite"
            )


class GrowthModel:
    """The UNGM as a `filters.smc.models.base.StateSpaceModel` (``d = m = 1``)."""

    state_dim = 1
    obs_dim = 1

    def __init__(self, params: GrowthModelParams | None = None) -> None:
        self.params = params if params is not None else GrowthModelParams()

    @property
    def Q(self) -> np.ndarray:
        return np.array([[self.params.q_var]])

    @property
    def R(self) -> np.ndarray:
        return np.array([[self.params.r_var]])

    def sample_initial(self, n: int, rng: np.random.Generator) -> np.ndarray:
        if n < 1:
            raise ValueError(f"need at least one particle, got n={n}")
        p = self.params
        return p.x0 + np.sqrt(p.init_var) * rng.standard_normal((n, 1))

    def transition_mean(self, x: np.ndarray, t: int) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        return 0.5 * x + 25.0 * x / (1.0 + x * x) + 8.0 * np.cos(1.2 * (t - 1))

    def sample_transition(self, x: np.ndarray, t: int, rng: np.random.Generator) -> np.ndarray:
        m = self.transition_mean(x, t)
        return m + np.sqrt(self.params.q_var) * rng.standard_normal(m.shape)

    def observe_mean(self, x: np.ndarray, t: int) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        return x * x / 20.0

    def log_likelihood(self, x: np.ndarray, y: np.ndarray, t: int) -> np.ndarray:
        r = self.params.r_var
        e = self.observe_mean(x, t)[:, 0] - float(np.asarray(y).reshape(-1)[0])
        return -0.5 * e * e / r - 0.5 * np.log(2.0 * np.pi * r)

    def simulate(self, T: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        if T < 1:
            raise ValueError(f"need T >= 1 steps, got {T}")
        xs = np.empty((T, 1))
        x = np.array([[self.params.x0]])
        for k in range(T):
            x = self.sample_transition(x, k + 1, rng)
            xs[k] = x[0]
        ys = self.observe_mean(xs, 0) + np.sqrt(self.params.r_var) * rng.standard_normal((T, 1))
        return xs, ys
