"""Firefly-improved particle filters: FA-PF and IFA-PF (paper 001, Cui et al. 2021).

Both insert a firefly-algorithm move between prediction and weighting of the
bootstrap filter (`filters.smc.pf.BootstrapPF`): each predicted particle is a
firefly whose *brightness* says how well it explains the newest data, and dim
fireflies move toward brighter ones::

    x_i += beta0 * exp(-gamma * r_ij^2) * (x_j - x_i) + alpha_i * (rand - 0.5)      (Eq. 4-6)

with ``beta0 = gamma = 1`` and ``rand ~ U[0, 1)`` per state component. Weights are then
the likelihood at the moved positions, as in Tian et al. 2016 (ref. [8] of the paper):
a heuristic, not a proper importance weight for the moved proposal.

* **FA-PF** (Tian et al. 2016): brightness ``I_i = exp(-||z_pred_i - y_t||^2 / (2R))``,
  fixed step ``alpha``, standard resampling (systematic by default).
* **IFA-PF** (paper 001): brightness also uses the distance of the predicted state to the
  filter's newest state estimate ``x_new`` (Eq. 2, **reconstructed**)::

      I_i = exp(-(||z_pred_i - y_t||^2 / (2R) + ||x_pred_i - x_new||^2 / (2Q)))

  adaptive step ``alpha_i = alpha0 * exp(-I_i / I_j)`` with ``alpha0`` scaled by the
  observation noise standard deviation ``sqrt(R)`` (Eq. 3, **reconstructed**), and the
  step-wise EWA resampling with Gaussian mutation (Eq. 7-8, `ewa_resample`).

The paper's Eq. 2 and 3 are images lost from the text; the forms above are the
project digest's reconstructions. Both are parameters here (``log_brightness``,
``step_factor``), so other monotone forms can be swapped in. ``x_new`` is never the
simulator's true state: by default it is the filter's own previous estimate pushed
through the noise-free transition, ``f(xhat_{t-1}, t)``; ``state_reference="posterior"``
uses instead the likelihood-weighted mean of the predicted particles at time ``t``.

**Who moves toward whom (vectorisation choice).** The textbook firefly loop moves every
``i`` toward every brighter ``j`` in turn, O(N^2) per generation. `firefly_move`
offers three array versions:

* ``"pairwise"``: the sequential loop over all brighter ``j`` in ascending brightness,
  composed in closed form (a product of convex steps, via suffix cumulative products);
  ``r_ij`` and ``x_j`` are taken from the positions before the move (synchronous update),
  and the random step is added once per firefly, not once per pair. Memory O(N^2 d).
* ``"sampled"``: each firefly moves toward one brighter firefly drawn uniformly among
  all strictly brighter ones. O(N d); the default for ``N > pairwise_max_n``.
* ``"brightest"``: every firefly moves toward the single brightest one. O(N d).

``"auto"`` (default) is pairwise up to ``pairwise_max_n = 200`` particles and sampled above.
For the adaptive step, ``I_j`` is the brightest firefly's brightness in the pairwise and
brightest modes, the drawn partner's in the sampled mode; the brightest firefly itself
gets ``I_i / I_j = 1``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from filters.numbers import is_int, is_real
from filters.smc.models.base import StateSpaceModel
from filters.smc.pf import BootstrapPF, PFConfig, normalise_log_weights
from filters.smc.resampling import normalise_weights

LogBrightnessFn = Callable[[np.ndarray, np.ndarray, float, float], np.ndarray]
"""``(obs_dist (N,), state_dist (N,), r_var, q_var) -> log I (N,)``; must decrease in both distances."""

StepFactorFn = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``(log I_i (N,), log I_j (N,)) -> factor (N,)``; the step is ``alpha_i = alpha0 * factor``."""

MOVE_MODES = ("auto", "pairwise", "sampled", "brightest")


# ---- brightness (Eq. 2) and step rule (Eq. 3) ---------------------------------------------------
def gaussian_log_brightness(obs_dist: np.ndarray, state_dist: np.ndarray, r_var: float, q_var: float) -> np.ndarray:
    """IFA-PF brightness, **reconstructed** Eq. 2: ``log I = -(d_z^2 / (2R) + d_x^2 / (2Q))``.

    ``obs_dist``: Euclidean distances ``||z_pred_i - z_new||`` (observation units);
    ``state_dist``: ``||x_pred_i - x_new||`` (state units); ``r_var``, ``q_var``: the
    observation and process noise variances (squared units). Returned in log form so that
    ratios ``I_i / I_j`` stay finite when both brightnesses underflow.
    """
    o = np.asarray(obs_dist, dtype=np.float64)
    s = np.asarray(state_dist, dtype=np.float64)
    return -(o * o / (2.0 * r_var) + s * s / (2.0 * q_var))


def observation_log_brightness(obs_dist: np.ndarray, state_dist: np.ndarray, r_var: float, q_var: float) -> np.ndarray:
    """Standard FA-PF brightness (Tian et al. 2016): ``log I = -d_z^2 / (2R)``; ignores ``state_dist``."""
    o = np.asarray(obs_dist, dtype=np.float64)
    return -(o * o) / (2.0 * r_var)


def fixed_step(log_i: np.ndarray, log_j: np.ndarray) -> np.ndarray:
    """Standard firefly step: factor 1, i.e. ``alpha_i = alpha0`` for every firefly."""
    return np.ones(np.shape(log_i))


def adaptive_step(log_i: np.ndarray, log_j: np.ndarray) -> np.ndarray:
    """IFA-PF step factor, **reconstructed** Eq. 3: ``exp(-I_i / I_j)``, in ``(0, 1]``.

    A firefly much dimmer than its partner (``I_i / I_j -> 0``) takes the full step ``alpha0``
    (global search); one as bright or brighter takes at most ``alpha0 / e`` (local refinement).
    Two fireflies whose brightnesses both underflowed (``log I = -inf``) count as equally bright (ratio 1).
    """
    li, lj = np.asarray(log_i, dtype=np.float64), np.asarray(log_j, dtype=np.float64)
    with np.errstate(invalid="ignore"):  # -inf - -inf is NaN: replaced by 0
        diff = np.where(li == lj, 0.0, li - lj)
    return np.exp(-np.exp(np.minimum(diff, 50.0)))


# ---- the firefly move -------------------------------------------------------------------------
def firefly_move(
    x: np.ndarray,
    log_brightness: np.ndarray,
    alpha0: float | np.ndarray,
    rng: np.random.Generator,
    *,
    step_factor: StepFactorFn = fixed_step,
    beta0: float = 1.0,
    gamma: float = 1.0,
    mode: str = "auto",
    pairwise_max_n: int = 200,
) -> np.ndarray:
    """One firefly generation on particles ``x`` ``(N, d)``; returns the moved copy ``(N, d)``.

    ``log_brightness`` ``(N,)``: log of each firefly's brightness (higher = brighter).
    ``alpha0``: random-step scale in state units, scalar or per component ``(d,)``.
    ``beta0``, ``gamma``: attractiveness at zero distance and light absorption (in 1/state-unit^2).
    ``mode``: see the module docstring. Draws ``N * d`` uniforms (plus ``N`` for "sampled") from ``rng``.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[0] == 0:
        raise ValueError(f"x must be a non-empty (N, d) array, got shape {x.shape}")
    n, d = x.shape
    log_i = np.asarray(log_brightness, dtype=np.float64)
    if log_i.shape != (n,):
        raise ValueError(f"log_brightness must be (N,)={n}, got shape {log_i.shape}")
    if np.any(np.isnan(log_i)):
        raise ValueError(
            f"log_brightness holds NaN for {int(np.isnan(log_i).sum())} of {n} fireflies (a likelihood that "
            "overflowed or an observation far outside the model's range?)"
        )
    if mode not in MOVE_MODES:
        raise ValueError(f"unknown firefly move mode {mode!r}; choose one of {MOVE_MODES}")
    if mode == "auto":
        mode = "pairwise" if n <= pairwise_max_n else "sampled"

    top = int(np.argmax(log_i))
    if mode == "pairwise":
        order = np.argsort(log_i, kind="stable")  # ascending brightness
        xs, ls = x[order], log_i[order]
        r2 = np.sum((xs[:, None, :] - xs[None, :, :]) ** 2, axis=-1)
        c = beta0 * np.exp(-gamma * r2) * (ls[None, :] > ls[:, None])  # c[i, j]: attraction of i to brighter j
        suffix = np.cumprod((1.0 - c)[:, ::-1], axis=1)[:, ::-1]  # prod_{k >= j} (1 - c_ik)
        after = np.concatenate([suffix[:, 1:], np.ones((n, 1))], axis=1)  # prod_{k > j} (1 - c_ik)
        moved = np.empty_like(x)
        moved[order] = suffix[:, :1] * xs + (c * after) @ xs
        log_j = np.full(n, log_i[top])
    else:
        if mode == "brightest":
            partner = np.full(n, top)
        else:  # sampled: uniform among strictly brighter fireflies, self if none
            order = np.argsort(log_i, kind="stable")
            ls = log_i[order]
            first = np.searchsorted(ls, log_i, side="right")  # sorted position of the first strictly brighter
            n_brighter = n - first
            pick = first + np.floor(rng.random(n) * n_brighter).astype(np.int64)
            partner = np.where(n_brighter > 0, order[np.minimum(pick, n - 1)], np.arange(n))
        diff = x[partner] - x
        att = beta0 * np.exp(-gamma * np.sum(diff * diff, axis=1)) * (log_i[partner] > log_i)
        moved = x + att[:, None] * diff
        log_j = np.where(log_i[partner] > log_i, log_i[partner], log_i)
    alpha = np.asarray(step_factor(log_i, log_j), dtype=np.float64)[:, None] * np.broadcast_to(alpha0, (d,))
    return moved + alpha * (rng.random((n, d)) - 0.5)


# ---- step-wise EWA resampling (Eq. 7-8) ---------------------------------------------------------
def ewa_threshold(weights_ascending: np.ndarray, beta: float = 0.8) -> float:
    """``dbar = mean(dhat)``: mean of the bias-corrected EWA curve of ascending weights (Eq. 7).

    ``d_i = beta d_{i-1} + (1 - beta) w_i``, ``d_0 = 0``, ``dhat_i = d_i / (1 - beta^i)``, i = 1..N.
    Each ``dhat_i`` is a weighted average of ``w_1..w_i`` so ``dbar <= max(w)``.
    """
    ws = np.asarray(weights_ascending, dtype=np.float64)
    d = lfilter([1.0 - beta], [1.0, -beta], ws)
    dhat = d / (1.0 - beta ** np.arange(1, ws.size + 1))
    return float(np.mean(dhat))


def ewa_resample(weights: np.ndarray, beta: float = 0.8, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """Step-wise resampling of paper 001 (Eq. 7-8); deterministic, returns ``(indices, mutate_mask)``.

    1. Sort the normalised weights ascending; threshold ``dbar`` = `ewa_threshold`.
    2. Keep particles with ``w_i >= dbar`` (the heaviest is always kept).
    3. Copy each kept particle ``ceil(w_i / dbar)`` times, heaviest first; trim to ``N``.
    4. If fewer than ``N``, fill with mutants of the kept particles taken in descending
       weight order (cycling if needed): those slots have ``mutate_mask = True`` and should
       become ``x' = x + x * mu * N(0, 1)`` (`apply_mutation`).

    ``indices`` ``(N,)`` int64 point into the input; ``mutate_mask`` ``(N,)`` bool.
    ``tol`` absorbs rounding (equal weights all survive with one copy each).
    Use it on any state type: FastSLAM applies the indices to whole particles and the
    mutation to poses only.
    """
    w = normalise_weights(weights)  # a sum that overflows included
    if not 0.0 <= beta < 1.0:
        raise ValueError(f"EWA beta must be in [0, 1), got {beta}")
    n = w.size
    order = np.argsort(w, kind="stable")
    dbar = ewa_threshold(w[order], beta)
    kept = order[w[order] >= dbar * (1.0 - tol)][::-1]  # descending weight
    copies = np.maximum(1, np.ceil(w[kept] / dbar - tol)).astype(np.int64)
    idx = np.repeat(kept, copies)[:n]
    n_fill = n - idx.size
    fill = kept[np.arange(n_fill) % kept.size]
    indices = np.concatenate([idx, fill]).astype(np.int64)
    mask = np.concatenate([np.zeros(idx.size, dtype=bool), np.ones(n_fill, dtype=bool)])
    return indices, mask


def apply_mutation(
    states: np.ndarray, indices: np.ndarray, mutate_mask: np.ndarray, mu: float, rng: np.random.Generator
) -> np.ndarray:
    """``states[indices]`` with the masked rows replaced by Gaussian mutants ``x + x * mu * N(0, 1)`` (Eq. 8).

    ``states`` ``(N, d)``; the perturbation is relative to each component's own value, so a
    zero component stays zero (as in the paper). Draws ``mask.sum() * d`` normals from ``rng``.
    """
    out = np.array(np.asarray(states, dtype=np.float64)[indices], copy=True)
    m = np.asarray(mutate_mask, dtype=bool)
    if m.any():
        sel = out[m]
        out[m] = sel + sel * mu * rng.standard_normal(sel.shape)
    return out


def check_firefly_settings(config) -> None:
    """ValueError naming the field unless ``config``'s firefly settings (shared by `FireflyConfig` and
    `filters.slam.ifa_fastslam.FireflySLAMConfig`) are usable: ``alpha0``, ``beta0``, ``gamma`` and
    ``mutation_mu`` finite numbers >= 0, ``ewa_beta`` in [0, 1), ``pairwise_max_n`` an int >= 1, ``use_ewa``
    a bool and ``move_mode`` one of `MOVE_MODES` (a NaN would only surface steps later, as NaN poses)."""
    name = type(config).__name__
    if config.move_mode not in MOVE_MODES:
        raise ValueError(f"{name}.move_mode: unknown {config.move_mode!r}; choose one of {MOVE_MODES}")
    for field in ("alpha0", "beta0", "gamma", "mutation_mu"):
        v = getattr(config, field)
        if not (is_real(v) and np.isfinite(v) and v >= 0):
            raise ValueError(f"{name}.{field} must be a finite number >= 0, got {v!r}")
    if not (is_real(config.ewa_beta) and 0.0 <= config.ewa_beta < 1.0):
        raise ValueError(f"{name}.ewa_beta must be in [0, 1), got {config.ewa_beta!r}")
    if not (is_int(config.pairwise_max_n) and config.pairwise_max_n >= 1):
        raise ValueError(f"{name}.pairwise_max_n must be an int >= 1, got {config.pairwise_max_n!r}")
    if not isinstance(config.use_ewa, (bool, np.bool_)):
        raise ValueError(f"{name}.use_ewa must be a bool, got {config.use_ewa!r}")


# ---- the filters ----------------------------------------------------------------------------
@dataclass(frozen=True)
class FireflyConfig(PFConfig):
    """Configuration of `FireflyPF` (adds to `filters.smc.pf.PFConfig`).

    alpha0: random-step scale (state units); IFA-PF multiplies it by ``sqrt(R)`` when
        ``scale_alpha_by_obs_noise`` is set.
    beta0, gamma: attractiveness at zero distance and light absorption (paper: 1, 1).
    n_moves: firefly generations per filter step.
    move_mode, pairwise_max_n: see `firefly_move`.
    state_reference: ``x_new`` in the brightness, ``"propagated"`` = ``f(xhat_{t-1}, t)`` or
        ``"posterior"`` = likelihood-weighted mean of the predicted particles.
    scale_alpha_by_obs_noise: ``alpha0 <- alpha0 * sqrt(mean diag R)``.
    use_ewa: step-wise EWA resampling + mutation instead of ``resampler``.
    ewa_beta, mutation_mu: EWA hyper-parameter (paper 0.8) and mutation scale (paper 0.01).
    """

    alpha0: float = 1.0
    beta0: float = 1.0
    gamma: float = 1.0
    n_moves: int = 1
    move_mode: str = "auto"
    pairwise_max_n: int = 200
    state_reference: str = "propagated"
    scale_alpha_by_obs_noise: bool = False
    use_ewa: bool = False
    ewa_beta: float = 0.8
    mutation_mu: float = 0.01

    def __post_init__(self) -> None:
        super().__post_init__()
        check_firefly_settings(self)
        if self.state_reference not in ("propagated", "posterior"):
            raise ValueError(f"state_reference must be 'propagated' or 'posterior', got {self.state_reference!r}")
        if not (is_int(self.n_moves) and self.n_moves >= 0):
            raise ValueError(f"FireflyConfig.n_moves must be an int >= 0, got {self.n_moves!r}")
        if not isinstance(self.scale_alpha_by_obs_noise, (bool, np.bool_)):
            v = self.scale_alpha_by_obs_noise
            raise ValueError(f"FireflyConfig.scale_alpha_by_obs_noise must be a bool, got {v!r}")


def fa_config(n_particles: int = 100, **kw) -> FireflyConfig:
    """FA-PF settings: fixed step, standard resampling."""
    return FireflyConfig(n_particles=n_particles, **kw)


def ifa_config(n_particles: int = 100, **kw) -> FireflyConfig:
    """IFA-PF settings: ``alpha0`` scaled by ``sqrt(R)``, EWA resampling with mutation."""
    kw.setdefault("scale_alpha_by_obs_noise", True)
    kw.setdefault("use_ewa", True)
    return FireflyConfig(n_particles=n_particles, **kw)


class FireflyPF(BootstrapPF):
    """Bootstrap PF with a firefly move before weighting; brightness and step rule are parameters.

    ``log_brightness``: a `LogBrightnessFn`; ``step_factor``: a `StepFactorFn`.
    ``run(model, ys, rng)`` returns filtered means ``(T, d)`` (see `filters.smc.pf.BootstrapPF`).
    """

    name = "FireflyPF"

    def __init__(
        self,
        config: FireflyConfig | None = None,
        log_brightness: LogBrightnessFn = observation_log_brightness,
        step_factor: StepFactorFn = fixed_step,
    ) -> None:
        super().__init__(config if config is not None else FireflyConfig())
        self.config: FireflyConfig
        self.log_brightness = log_brightness
        self.step_factor = step_factor

    def state_reference(
        self, model: StateSpaceModel, x_pred: np.ndarray, y: np.ndarray, t: int, x_prev_est: np.ndarray
    ) -> np.ndarray:
        """``x_new`` ``(d,)``: the filter's own newest state estimate (never the true state)."""
        if self.config.state_reference == "posterior":
            return normalise_log_weights(model.log_likelihood(x_pred, y, t)) @ x_pred
        return model.transition_mean(np.asarray(x_prev_est, dtype=np.float64)[None, :], t)[0]

    def move(self, model, x_pred, y, t, x_prev_est, rng):
        cfg = self.config
        r_var = float(np.mean(np.diag(model.R)))
        q_var = float(np.mean(np.diag(model.Q)))
        alpha0 = cfg.alpha0 * (np.sqrt(r_var) if cfg.scale_alpha_by_obs_noise else 1.0)
        x_new = self.state_reference(model, x_pred, y, t, x_prev_est)
        x = x_pred
        for _ in range(cfg.n_moves):
            obs_dist = np.linalg.norm(model.observe_mean(x, t) - y[None, :], axis=1)
            state_dist = np.linalg.norm(x - x_new[None, :], axis=1)
            log_i = self.log_brightness(obs_dist, state_dist, r_var, q_var)
            x = firefly_move(
                x,
                log_i,
                alpha0,
                rng,
                step_factor=self.step_factor,
                beta0=cfg.beta0,
                gamma=cfg.gamma,
                mode=cfg.move_mode,
                pairwise_max_n=cfg.pairwise_max_n,
            )
        return x

    def resample(self, x, w, rng):
        if not self.config.use_ewa:
            return super().resample(x, w, rng)
        idx, mask = ewa_resample(w, self.config.ewa_beta)
        return apply_mutation(x, idx, mask, self.config.mutation_mu, rng)


class FAPF(FireflyPF):
    """FA-PF (Tian et al. 2016): observation brightness, fixed step ``alpha0``, standard resampling."""

    name = "FA-PF"

    def __init__(self, config: FireflyConfig | None = None) -> None:
        super().__init__(config if config is not None else fa_config(), observation_log_brightness, fixed_step)


class IFAPF(FireflyPF):
    """IFA-PF (paper 001): reconstructed Eq. 2 brightness, adaptive Eq. 3 step, EWA resampling (Eq. 7-8).

    Build the config with `ifa_config` (``alpha0`` scaled by ``sqrt(R)``, EWA on).
    """

    name = "IFA-PF"

    def __init__(
        self,
        config: FireflyConfig | None = None,
        log_brightness: LogBrightnessFn = gaussian_log_brightness,
        step_factor: StepFactorFn = adaptive_step,
    ) -> None:
        super().__init__(config if config is not None else ifa_config(), log_brightness, step_factor)
