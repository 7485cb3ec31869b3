"""Extra reward terms for the ``SemReloc`` envs (v1 and newer), kept out of the env (its reward logic is fixed there).

* `belief_mass_near` — the share of the belief within ``radius_m`` of a pose: Active
  Neural Localization's reward (Chaplot et al., ICLR 2018: the belief's probability at the
  true pose), for a particle belief.
* `BeliefMassReward` — a wrapper adding it as the named term ``belief_mass`` to
  ``info["rewards"]`` and to the reward.

A reward may use the truth (it is the training signal, not an observation); the policy's
observation never does.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np

from filters.numbers import is_real
from filters.pose import wrap_angle

from .wrappers import find_wrapper

BELIEF_MASS_RADIUS_M = 0.5
"""Default radius of `belief_mass_near`: the env's success radius."""


def belief_mass_near(
    poses: np.ndarray,
    weights: np.ndarray,
    pose,
    radius_m: float = BELIEF_MASS_RADIUS_M,
    heading_tol_rad: float | None = None,
) -> float:
    """Share of the total weight on particles within ``radius_m`` (and, if given,
    ``heading_tol_rad``) of ``pose``; in ``[0, 1]``.

    Args:
        poses: ``(N, 3)`` particles ``(x m, y m, theta rad)``.
        weights: ``(N,)`` non-negative weights (normalised here).
        pose: ``(3,)`` reference pose (the truth, for a reward).

    Raises:
        ValueError: bad shapes, a non-positive radius, or weights all zero / negative / non-finite.
    """
    p = np.asarray(poses, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    ref = np.asarray(pose, dtype=np.float64).reshape(-1)
    if p.ndim != 2 or p.shape[1] != 3 or w.shape != (p.shape[0],) or ref.shape != (3,):
        raise ValueError(f"need poses (N, 3), weights (N,), pose (3,); got {p.shape}, {w.shape}, {ref.shape}")
    if not (math.isfinite(radius_m) and radius_m > 0):
        raise ValueError(f"radius_m must be positive, got {radius_m!r}")
    if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError("weights must be finite, non-negative and not all zero")
    near = np.hypot(p[:, 0] - ref[0], p[:, 1] - ref[1]) < radius_m
    if heading_tol_rad is not None:
        near &= np.abs(wrap_angle(p[:, 2] - ref[2])) < heading_tol_rad
    return float(np.clip(w[near].sum() / w.sum(), 0.0, 1.0))


class BeliefMassReward(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Add ``weight * belief_mass_near(particles, truth)`` as the reward term ``belief_mass``.

    ``mode="level"`` pays the mass every step (as Active Neural Localization); ``mode="gain"``
    pays its change since the last step (since the reset, on the first step), so a policy is not paid for
    lingering once the belief is right. The term is added to ``info["rewards"]`` and to the
    reward; everything else passes through.

    Args:
        env: a ``SemReloc`` env, v1 or newer (``unwrapped.mcl`` and ``unwrapped.world``).
        weight: scale of the term (reward units per unit of mass).
        radius_m: see `belief_mass_near`.
        heading_tol_rad: see `belief_mass_near`.
        mode: ``"level"`` or ``"gain"``.
    """

    def __init__(
        self,
        env: gym.Env,
        weight: float = 0.05,
        radius_m: float = BELIEF_MASS_RADIUS_M,
        heading_tol_rad: float | None = None,
        mode: str = "level",
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self, weight=weight, radius_m=radius_m, heading_tol_rad=heading_tol_rad, mode=mode
        )
        gym.Wrapper.__init__(self, env)
        if mode not in ("level", "gain"):
            raise ValueError(f"mode must be 'level' or 'gain', got {mode!r}")
        if not (is_real(weight) and math.isfinite(weight)):
            raise ValueError(f"weight must be a finite number, got {weight!r:.60}")
        if not (is_real(radius_m) and math.isfinite(radius_m) and radius_m > 0):
            raise ValueError(f"radius_m must be a positive number, got {radius_m!r:.60}")
        if heading_tol_rad is not None and not (is_real(heading_tol_rad) and 0 < heading_tol_rad <= math.pi):
            raise ValueError(f"heading_tol_rad must be None or a number in (0, pi], got {heading_tol_rad!r:.60}")
        if not (hasattr(env.unwrapped, "mcl") and hasattr(env.unwrapped, "world")):
            raise TypeError(f"BeliefMassReward needs a SemReloc env (its filter and world), got {env.unwrapped}")
        if find_wrapper(env, BeliefMassReward) is not None:
            raise ValueError(
                "the env has a BeliefMassReward already: a second would overwrite its info['rewards']['belief_mass'] "
                "and the terms would no longer sum to the reward"
            )
        self.weight, self.radius_m, self.mode = float(weight), float(radius_m), mode
        self.heading_tol_rad = None if heading_tol_rad is None else float(heading_tol_rad)
        self._prev: float | None = None

    def mass(self) -> float:
        """The current belief mass near the true pose."""
        base = self.env.unwrapped
        return belief_mass_near(base.mcl.poses, base.mcl.weights, base.world.pose, self.radius_m, self.heading_tol_rad)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self._prev = self.mass()
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        m = self.mass()
        term = self.weight * (m if self.mode == "level" else m - self._prev)
        self._prev = m
        info["rewards"] = {**info.get("rewards", {}), "belief_mass": term}
        return obs, float(reward) + term, terminated, truncated, info
