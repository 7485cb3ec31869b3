"""The state-space model protocol every particle filter in `filters` runs on.

Time convention: the hidden state starts at ``x_0`` (time 0, never observed);
for ``t = 1, 2, ..., T`` the state moves ``x_{t-1} -> x_t`` and is observed as
``y_t``. Arrays of particles have shape ``(N, d)`` with ``d = state_dim``; an
observation has shape ``(m,)`` with ``m = obs_dim``. Every method that draws takes
a ``np.random.Generator``; none touches ``np.random`` globals.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class StateSpaceModel(Protocol):
    """A Markov state-space model ``x_t ~ p(. | x_{t-1}, t)``, ``y_t ~ p(. | x_t, t)``.

    Attributes
    ----------
    state_dim, obs_dim:
        ``d`` and ``m``.
    Q, R:
        Process and observation noise covariances, ``(d, d)`` and ``(m, m)``, in the
        squared units of state and observation. Filters use them as scales (e.g. the
        firefly brightness); exact likelihoods come from `log_likelihood`.
    """

    state_dim: int
    obs_dim: int

    @property
    def Q(self) -> np.ndarray: ...

    @property
    def R(self) -> np.ndarray: ...

    def sample_initial(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` draws from the filter's prior on ``x_0``, shape ``(n, d)``."""
        ...

    def sample_transition(self, x: np.ndarray, t: int, rng: np.random.Generator) -> np.ndarray:
        """One draw of ``x_t`` for each row of ``x = x_{t-1}`` ``(N, d)``; returns ``(N, d)``."""
        ...

    def transition_mean(self, x: np.ndarray, t: int) -> np.ndarray:
        """Noise-free ``E[x_t | x_{t-1} = x]`` for each row of ``x`` ``(N, d)``; returns ``(N, d)``."""
        ...

    def observe_mean(self, x: np.ndarray, t: int) -> np.ndarray:
        """Noise-free predicted observation ``E[y_t | x_t = x]``, ``(N, d) -> (N, m)``."""
        ...

    def log_likelihood(self, x: np.ndarray, y: np.ndarray, t: int) -> np.ndarray:
        """``log p(y_t = y | x_t = x)`` for each row of ``x`` ``(N, d)``, ``y`` ``(m,)``; returns ``(N,)``."""
        ...

    def simulate(self, T: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """A ground-truth run: states ``(T, d)`` for ``t = 1..T`` and observations ``(T, m)``."""
        ...
