"""Generic bootstrap (SIR) particle filter over any `filters.smc.models.base.StateSpaceModel`.

One step for ``t = 1..T`` (Gordon, Salmond & Smith 1993)::

    x_t^i ~ p(x_t | x_{t-1}^i)                     predict (model.sample_transition)
    x_t^i <- move(x_t^i)                           hook; identity here, firefly moves in filters.smc.firefly
    log w^i += log p(y_t | x_t^i)                  weight, normalised by log-sum-exp
    xhat_t = sum_i w^i x_t^i                       filtered mean (the returned estimate)
    resample when ESS < resample_threshold * N     hook; a scheme from filters.smc.resampling by name

All particle arithmetic is array code over ``(N, d)``; the only Python loop is over time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from filters.numbers import is_int
from filters.smc.models.base import StateSpaceModel
from filters.smc.resampling import effective_sample_size, get_resampler


@dataclass(frozen=True)
class PFConfig:
    """Configuration of `BootstrapPF`.

    n_particles: ``N >= 1``.
    resampler: a name in `filters.smc.resampling.RESAMPLERS`.
    resample_threshold: resample when ``ESS < resample_threshold * N``; any value ``>= 1``
        resamples at every step (plain SIR, the paper-001 setting).
    """

    n_particles: int = 100
    resampler: str = "systematic"
    resample_threshold: float = 1.0

    def __post_init__(self) -> None:
        if not is_int(self.n_particles) or self.n_particles < 1:
            raise ValueError(f"n_particles must be a positive integer, got {self.n_particles!r}")
        if not self.resample_threshold >= 0:
            raise ValueError(f"resample_threshold must be >= 0, got {self.resample_threshold!r}")
        get_resampler(self.resampler)  # unknown name -> ValueError now, not mid-run


def check_observations(ys: np.ndarray, obs_dim: int) -> np.ndarray:
    """``ys`` as a finite float array ``(T, obs_dim)``; ``ValueError`` on NaN/inf, wrong shape or ``T = 0``."""
    y = np.asarray(ys, dtype=np.float64)
    if y.ndim == 1 and obs_dim == 1:
        y = y[:, None]
    if y.ndim != 2 or y.shape[1] != obs_dim or y.shape[0] == 0:
        raise ValueError(f"observations must have shape (T>0, {obs_dim}), got {np.shape(ys)}")
    if not np.all(np.isfinite(y)):
        raise ValueError("observations contain NaN or inf")
    return y


def normalise_log_weights(logw: np.ndarray) -> np.ndarray:
    """Normalised weights ``exp(logw - logsumexp(logw))``. All ``-inf`` (or NaN) -> uniform, a documented fallback;
    ``+inf`` entries share the whole mass equally (the limit of their weight growing without bound)."""
    logw = np.where(np.isnan(logw), -np.inf, logw)
    if np.any(np.isposinf(logw)):
        top_mask = np.isposinf(logw)
        return top_mask / np.count_nonzero(top_mask)
    top = np.max(logw)
    if not np.isfinite(top):
        return np.full(logw.shape, 1.0 / logw.size)
    return np.exp(logw - logsumexp(logw))


class BootstrapPF:
    """Bootstrap SIR particle filter; subclasses override `move` and `resample`.

    ``run(model, ys, rng)`` returns the filtered means ``(T, d)``; row ``k`` estimates
    ``x_{k+1}`` from ``y_1..y_{k+1}``. The same ``rng`` state gives bit-identical output.
    """

    name = "PF"

    def __init__(self, config: PFConfig | None = None) -> None:
        self.config = config if config is not None else PFConfig()

    # ---- hooks -------------------------------------------------------------------------------
    def move(
        self,
        model: StateSpaceModel,
        x_pred: np.ndarray,
        y: np.ndarray,
        t: int,
        x_prev_est: np.ndarray,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """Move predicted particles ``(N, d)`` before weighting; identity for the plain PF.

        ``x_prev_est`` ``(d,)`` is the filter's own estimate of ``x_{t-1}`` (never a true state).
        """
        return x_pred

    def resample(self, x: np.ndarray, w: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """New equally weighted particle set ``(N, d)`` from particles ``x`` with normalised weights ``w``."""
        return x[get_resampler(self.config.resampler)(w, rng)]

    # ---- loop --------------------------------------------------------------------------------
    def run(self, model: StateSpaceModel, ys: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Filter observations ``ys`` ``(T, m)`` (``(T,)`` allowed when ``m = 1``); returns means ``(T, d)``.

        Raises:
            TypeError: ``rng`` is not a ``numpy.random.Generator``.
            ValueError: malformed ``ys``.
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(
                f"rng must be a numpy.random.Generator (no hidden global randomness), got {type(rng).__name__}"
            )
        y_all = check_observations(ys, model.obs_dim)
        n = self.config.n_particles
        x = np.asarray(model.sample_initial(n, rng), dtype=np.float64).reshape(n, model.state_dim)
        logw = np.full(n, -np.log(n))
        est = x.mean(axis=0)
        means = np.empty((y_all.shape[0], model.state_dim))
        for k, y in enumerate(y_all):
            t = k + 1
            x = model.sample_transition(x, t, rng)
            x = self.move(model, x, y, t, est, rng)
            w = normalise_log_weights(logw + model.log_likelihood(x, y, t))
            est = w @ x
            means[k] = est
            thr = self.config.resample_threshold
            if thr >= 1.0 or effective_sample_size(w) < thr * n:
                x = self.resample(x, w, rng)
                logw = np.full(n, -np.log(n))
            else:
                with np.errstate(divide="ignore"):
                    logw = np.log(w)
        return means


def rmse(estimates: np.ndarray, truth: np.ndarray) -> float:
    """Root-mean-square error over all steps and state components (same units as the state)."""
    e = np.asarray(estimates, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    return float(np.sqrt(np.mean(e * e)))
