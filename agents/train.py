"""Train PPO on ``SemReloc-v1`` and evaluate any policy (SB3 model or callable baseline) on fixed seeds.

* :class:`TrainConfig` — every knob of a training run (env keyword arguments, vectorisation,
  PPO hyper-parameters, network sizes, seed).
* :func:`make_env` — ``gym.make("SemReloc-v1", **env_kwargs)`` wrapped in
  :class:`~semreloc_env.wrappers.BeliefObservation` (the policy sees the belief summary, not the pose).
* :func:`train` — builds the vectorised envs and PPO (``MultiInputPolicy`` with
  :class:`~agents.features.SemRelocExtractor`), learns, returns the model.
* :func:`evaluate` — runs ``n_episodes`` episodes, episode ``i`` reset with seed ``seed + i``, and
  returns :func:`agents.metrics.summarize_episodes` of them. The same seeds give the same start
  poses, sensor noise and filter draws for every policy evaluated, so policies are compared on
  identical episodes.

Every random draw is seeded: PPO and its network from ``TrainConfig.seed``, training env ``k``
from ``seed + k`` (SB3 ``make_vec_env``), evaluation episodes from their own seeds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

import semreloc_env  # noqa: F401  (registers the envs)
from semreloc_env.wrappers import BeliefObservation

from .callbacks import ProgressCallback, RelocalizationMetricsCallback
from .features import SemRelocExtractor
from .metrics import EpisodeTracker, summarize_episodes

ENV_ID = "SemReloc-v1"
VEC_ENVS = {"dummy": DummyVecEnv, "subproc": SubprocVecEnv, "batched": None}
"""``"batched"``: :class:`agents.vec_env.SB3VecEnvAdapter` over the batched env (R robots in one process)."""


@dataclass(frozen=True)
class TrainConfig:
    """One PPO training run on ``SemReloc-v1``.

    Attributes:
        env_kwargs: ``gym.make`` keyword arguments (e.g. ``layout``, ``semantic``, ``relocalizer``,
            ``max_episode_steps``); unknown ones are errors, as in the env.
        n_envs: parallel envs.
        vec_env: ``"dummy"`` (one process), ``"subproc"`` (one process per env) or ``"batched"``
            (:class:`semreloc_env.envs.batched.SemRelocLoopVectorEnv` through :class:`agents.vec_env.SB3VecEnvAdapter`:
            one process, the same episodes as ``"dummy"``).
        total_timesteps: env steps to train for (summed over envs).
        seed: seeds PPO (network init, action sampling, minibatches) and the envs (``seed + k``).
        n_steps: steps per env per rollout (rollout size ``n_steps * n_envs``).
        batch_size: minibatch size.
        n_epochs: passes over each rollout.
        learning_rate: Adam step size.
        gamma: discount per step (0.1 s).
        gae_lambda: GAE lambda.
        ent_coef: entropy bonus weight.
        clip_range: PPO ratio clip.
        features_dim: output size of :class:`~agents.features.SemRelocExtractor`.
        net_arch: hidden sizes of the policy and value heads after the extractor.
        torch_threads: ``torch.set_num_threads`` (small nets are fastest on 1 thread).
        log_dir: where SB3 writes ``progress.csv`` (None: stdout only).
        verbose: SB3 verbosity (1 prints the log table every rollout).
        progress_every_s: seconds between progress lines on stderr (None: none).
        metrics_window: episodes the logged relocalization rates are taken over.
    """

    env_kwargs: dict[str, Any] = field(default_factory=dict)
    n_envs: int = 4
    vec_env: str = "dummy"
    total_timesteps: int = 100_000
    seed: int = 0
    n_steps: int = 256
    batch_size: int = 256
    n_epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    ent_coef: float = 0.01
    clip_range: float = 0.2
    features_dim: int = 128
    net_arch: tuple[int, ...] = (64, 64)
    torch_threads: int = 1
    log_dir: str | None = None
    verbose: int = 0
    progress_every_s: float | None = 30.0
    metrics_window: int = 100

    def __post_init__(self) -> None:
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env must be one of {list(VEC_ENVS)}, got {self.vec_env!r}")
        for name in ("n_envs", "total_timesteps", "n_steps", "batch_size", "n_epochs", "torch_threads"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def make_env(env_kwargs: dict[str, Any] | None = None, belief: bool = True) -> gym.Env:
    """``SemReloc-v1`` with ``env_kwargs``, wrapped in :class:`BeliefObservation` when ``belief``."""
    env = gym.make(ENV_ID, **dict(env_kwargs or {}))
    return BeliefObservation(env) if belief else env


def make_venv(config: TrainConfig):
    """The training ``VecEnv`` of ``config``: env ``k`` seeded ``config.seed + k``, each in SB3's ``Monitor``."""
    env_kwargs = dict(config.env_kwargs)
    if config.vec_env == "batched":
        from stable_baselines3.common.monitor import Monitor

        from semreloc_env.envs.batched import SemRelocLoopVectorEnv

        from .vec_env import SB3VecEnvAdapter

        venv = SB3VecEnvAdapter(
            SemRelocLoopVectorEnv(
                num_envs=config.n_envs, env_id=ENV_ID, wrapper=lambda e: Monitor(BeliefObservation(e)), **env_kwargs
            )
        )
        venv.seed(config.seed)
        return venv
    return make_vec_env(
        lambda: make_env(env_kwargs),
        n_envs=config.n_envs,
        seed=config.seed,
        vec_env_cls=VEC_ENVS[config.vec_env],
    )


def train(config: TrainConfig, callbacks: Sequence[BaseCallback] = ()) -> PPO:
    """Train PPO as ``config`` says and return the model.

    A :class:`~agents.callbacks.RelocalizationMetricsCallback` always runs (its keys appear in the
    log and in ``log_dir/progress.csv``), plus a progress line when ``config.progress_every_s`` is set,
    plus ``callbacks``. The model's env is left open; ``model.get_env().close()`` releases it.
    """
    torch.set_num_threads(int(config.torch_threads))
    venv = make_venv(config)
    model = PPO(
        "MultiInputPolicy",
        venv,
        n_steps=config.n_steps,
        batch_size=config.batch_size,
        n_epochs=config.n_epochs,
        learning_rate=config.learning_rate,
        gamma=config.gamma,
        gae_lambda=config.gae_lambda,
        ent_coef=config.ent_coef,
        clip_range=config.clip_range,
        policy_kwargs={
            "features_extractor_class": SemRelocExtractor,
            "features_extractor_kwargs": {"features_dim": config.features_dim},
            "net_arch": list(config.net_arch),
        },
        seed=config.seed,
        device="cpu",
        verbose=config.verbose,
    )
    formats = ["stdout"] if config.verbose else []
    if config.log_dir is not None:
        formats.append("csv")
    model.set_logger(configure(config.log_dir, formats))
    cbs: list[BaseCallback] = [RelocalizationMetricsCallback(window=config.metrics_window)]
    if config.progress_every_s is not None:
        cbs.append(ProgressCallback(config.total_timesteps, every_s=config.progress_every_s))
    cbs.extend(callbacks)
    model.learn(total_timesteps=config.total_timesteps, callback=cbs)
    return model


def _as_action_fn(model_or_policy: Any, deterministic: bool) -> tuple[Callable[[dict], Any], Callable[[], None]]:
    if isinstance(model_or_policy, BaseAlgorithm):

        def act(obs: dict):
            action, _ = model_or_policy.predict(obs, deterministic=deterministic)
            return action

        return act, lambda: None
    if not callable(model_or_policy):
        raise TypeError(f"expected an SB3 model or a callable obs -> action, got {type(model_or_policy).__name__}")
    reset = getattr(model_or_policy, "reset", None)
    return model_or_policy, (reset if callable(reset) else lambda: None)


def evaluate(
    model_or_policy: Any,
    env_kwargs: dict[str, Any] | None = None,
    n_episodes: int = 20,
    seed: int = 0,
    deterministic: bool = True,
    return_episodes: bool = False,
) -> dict[str, Any]:
    """Run ``n_episodes`` episodes of ``model_or_policy`` and summarise them.

    Args:
        model_or_policy: an SB3 model (``BaseAlgorithm``; acts with ``predict``) or a callable
            ``obs dict -> action`` such as :class:`agents.baselines.WallFollowExplorer` (its ``reset()``
            is called at every episode start, if it has one). Callables see the same observation
            as models, including the ``belief`` key.
        env_kwargs: ``gym.make("SemReloc-v1", ...)`` keyword arguments (``max_episode_steps`` too).
        n_episodes: episodes; episode ``i`` starts with ``reset(seed=seed + i)``.
        seed: first episode seed.
        deterministic: SB3 models act greedily (ignored for callables).
        return_episodes: add ``"per_episode"``: the list of :meth:`EpisodeResult.as_dict`.

    Returns:
        :func:`agents.metrics.summarize_episodes` of the episodes: ``success_rate``,
        ``wrong_convergence_rate``, ``unconverged_rate``, ``first_convergence_wrong_rate`` in
        ``[0, 1]``, ``median_steps_to_converge`` (steps, None if nothing succeeded), median final
        errors (m, rad), mean length and return. Equal inputs (and a policy in the same state) give
        an equal dict.
    """
    if n_episodes < 1:
        raise ValueError(f"n_episodes must be >= 1, got {n_episodes}")
    env = make_env(env_kwargs)
    if isinstance(model_or_policy, BaseAlgorithm) and model_or_policy.observation_space != env.observation_space:
        env.close()
        raise ValueError(
            f"the model observes {model_or_policy.observation_space}, the env gives {env.observation_space}: "
            "evaluate it with the env_kwargs it was trained with"
        )
    act, reset_policy = _as_action_fn(model_or_policy, deterministic)
    discrete = isinstance(env.action_space, gym.spaces.Discrete)
    results = []
    tracker = EpisodeTracker()
    try:
        for i in range(n_episodes):
            obs, info = env.reset(seed=int(seed) + i)
            reset_policy()
            tracker.reset()
            tracker.observe(info, is_step=False)
            done = False
            while not done:
                action = act(obs)
                action = int(action) if discrete else np.asarray(action, dtype=np.float32)
                obs, reward, terminated, truncated, info = env.step(action)
                tracker.observe(info, reward)
                done = terminated or truncated
            results.append(tracker.finish())
    finally:
        env.close()
    summary: dict[str, Any] = summarize_episodes(results)
    if return_episodes:
        summary["per_episode"] = [r.as_dict() for r in results]
    return summary
