"""Train PPO on ``SemReloc-v22`` and evaluate any policy (SB3 model or callable baseline) on fixed seeds.

* `TrainConfig` — every knob of a training run (env keyword arguments, vectorisation,
  PPO hyper-parameters, network sizes, seed).
* `make_env` — ``gym.make("SemReloc-v22", **env_kwargs)`` wrapped in
  `BeliefObservation` (the policy sees the belief summary, not the pose).
* `train` — builds the vectorised envs and PPO (`SemRelocPolicy`: SB3's ``MultiInputPolicy``, with
  `SemRelocExtractor`), learns, returns the model. With a ``log_dir`` it
  writes there, and only there: ``progress.csv``, TensorBoard event files (``tensorboard --logdir
  LOG_DIR``), checkpoints (``checkpoints/``) and the periodic evaluation (``eval/evaluations.npz``,
  ``eval/best_model.zip``; its ``eval/success_rate`` comes from the env's ``info["is_success"]``).
* `evaluate` — runs ``n_episodes`` episodes, episode ``i`` reset with seed ``seed + i``, and
  returns `agents.metrics.summarize_episodes` of them. The same seeds give the same start
  poses, sensor noise and filter draws for every policy evaluated, so policies are compared on
  identical episodes.

Every random draw is seeded: PPO and its network from ``TrainConfig.seed``, training env ``k``
from ``seed + k`` (SB3 ``make_vec_env``), evaluation episodes from their own seeds.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import sys
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.callbacks import BaseCallback, CheckpointCallback, EvalCallback
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.logger import HumanOutputFormat, Logger, configure
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

import semreloc_env  # noqa: F401  (registers the envs)
from filters.numbers import is_int, is_real
from semreloc_env.wrappers import BeliefObservation

from .callbacks import RelocalizationMetricsCallback
from .features import SemRelocExtractor, SemRelocPolicy
from .metrics import EpisodeTracker, summarize_episodes
from .vec_env import close_after_interrupt

ENV_ID = "SemReloc-v22"
"""The env id training and evaluation use unless told otherwise (``TrainConfig.env_id``, ``env_id=``)."""
VEC_ENVS = {"dummy": DummyVecEnv, "subproc": SubprocVecEnv, "batched": None}
"""``"batched"``: `agents.vec_env.SB3VecEnvAdapter` over the batched env (R robots in one process)."""


def check_ppo_settings(config) -> None:
    """ValueError naming the field unless ``config``'s PPO numbers are usable: ``learning_rate`` and
    ``clip_range`` finite and > 0, ``gamma`` in (0, 1], ``gae_lambda`` in [0, 1], ``ent_coef`` and
    ``vf_coef`` (where present) finite and >= 0, the layer sizes ``features_dim``, ``net_arch`` and
    ``cnn_channels`` (where present) ints >= 1, ``device`` ``"auto"`` or a torch device."""
    checks = {
        "learning_rate": (lambda v: v > 0, "> 0"),
        "clip_range": (lambda v: v > 0, "> 0"),
        "gamma": (lambda v: 0 < v <= 1, "in (0, 1]"),
        "gae_lambda": (lambda v: 0 <= v <= 1, "in [0, 1]"),
        "ent_coef": (lambda v: v >= 0, ">= 0"),
        "vf_coef": (lambda v: v >= 0, ">= 0"),
    }
    for name, (ok, what) in checks.items():
        if not hasattr(config, name):
            continue
        v = getattr(config, name)
        if not (is_real(v) and math.isfinite(v) and ok(v)):
            raise ValueError(f"{name} must be a finite number {what}, got {v!r}")
    for name in ("features_dim", "net_arch", "cnn_channels"):  # layer sizes: SB3 and torch fail without naming them
        if not hasattr(config, name):
            continue
        v = getattr(config, name)
        sizes = [v] if name == "features_dim" else list(v) if isinstance(v, (list, tuple)) else [None]
        if not all(is_int(k) and k >= 1 for k in sizes):
            raise ValueError(f"{name} must be {'an int' if name == 'features_dim' else 'ints'} >= 1, got {v!r}")
    if hasattr(config, "n_steps") and hasattr(config, "n_envs") and int(config.n_steps) * int(config.n_envs) < 2:
        raise ValueError(
            f"n_steps * n_envs (the rollout) must be at least 2 for PPO, got {config.n_steps} * {config.n_envs}"
        )
    check_device(config.device)


PPO_HYPERPARAMETERS = (
    "n_steps",
    "batch_size",
    "n_epochs",
    "learning_rate",
    "gamma",
    "gae_lambda",
    "ent_coef",
    "clip_range",
)
"""The PPO arguments a training config (`TrainConfig`, `agents.train_active.ActiveTrainConfig`) holds as fields."""


def log_formats(verbose: int) -> list[str]:
    """SB3 logger formats of a training run: stdout with ``verbose``, the CSV, and TensorBoard's events where the
    ``tensorboard`` package is installed (the ``rl`` extra; without it a run logs the CSV alone, and says so)."""
    if importlib.util.find_spec("tensorboard") is None:
        print(
            "note: tensorboard is not installed (the 'rl' extra): no TensorBoard events, progress.csv only", flush=True
        )
        return (["stdout"] if verbose else []) + ["csv"]
    return (["stdout"] if verbose else []) + ["csv", "tensorboard"]


def progress_bar_wanted(wanted: bool) -> bool:
    """``wanted``, unless SB3's progress bar cannot run here (it needs ``tqdm`` and ``rich``, the ``rl`` extra): then
    False, with a note, rather than a failed run."""
    if wanted and importlib.util.find_spec("rich") is None:
        print("note: rich is not installed (the 'rl' extra): training without SB3's progress bar", flush=True)
        return False
    return bool(wanted)


def ppo_hyperparameters(config) -> dict[str, Any]:
    """``config``'s `PPO_HYPERPARAMETERS` as SB3 ``PPO`` keyword arguments."""
    return {name: getattr(config, name) for name in PPO_HYPERPARAMETERS}


def check_device(device) -> None:
    """ValueError unless ``device`` is ``"auto"`` or names a torch device (``"cpu"``, ``"cuda:0"``, ...) that this
    machine has (SB3 would quietly train on the CPU instead of a CUDA device it does not find)."""
    if device == "auto":
        return
    try:
        kind = torch.device(device).type
    except (RuntimeError, TypeError) as e:
        raise ValueError(f"device must be 'auto' or a torch device such as 'cpu', got {device!r}") from e
    if kind == "cuda" and not torch.cuda.is_available():
        raise ValueError(
            f"device {device!r}: torch finds no CUDA device here (torch.cuda.is_available() is False); "
            "use 'cpu', or 'auto' to take a GPU only where there is one"
        )


@dataclass(frozen=True)
class TrainConfig:
    """One PPO training run on ``SemReloc-v22`` (or ``env_id``).

    Attributes:
        env_id: the registered single-robot env (``"SemReloc-v22"``; ``"SemReloc-v1"`` has the flat
            observation that models trained before v2 expect).
        env_kwargs: ``gym.make`` keyword arguments (e.g. ``layout``, ``semantic``, ``relocalizer``,
            ``max_episode_steps``); unknown ones are errors, as in the env.
        n_envs: parallel envs.
        vec_env: ``"dummy"`` (one process), ``"subproc"`` (one process per env) or ``"batched"``
            (`semreloc_env.envs.batched.SemRelocLoopVectorEnv` through `agents.vec_env.SB3VecEnvAdapter`:
            one process, the same episodes as ``"dummy"``; in ``workers`` processes with ``workers > 1``).
        workers: processes the ``"batched"`` robots are split over (`agents.worker_vec_env.WorkersVecEnv`, the same
            episodes as in one process; 1: this process). At most ``n_envs``; other vec envs take 1 only.
        total_timesteps: env steps to train for (summed over envs). SB3 stops at the end of a rollout,
            so a run trains a whole number of rollouts (``n_steps * n_envs`` steps each), at least one:
            a smaller value still trains one rollout (the progress bar then shows e.g. "512/64").
        seed: seeds PPO (network init, action sampling, minibatches) and the envs (``seed + k``).
        n_steps: steps per env per rollout (rollout size ``n_steps * n_envs``).
        batch_size: minibatch size.
        n_epochs: passes over each rollout.
        learning_rate: Adam step size.
        gamma: discount per step (0.1 s).
        gae_lambda: GAE lambda.
        ent_coef: entropy bonus weight.
        clip_range: PPO ratio clip.
        features_dim: output size of `SemRelocExtractor`.
        net_arch: hidden sizes of the policy and value heads after the extractor.
        torch_threads: ``torch.set_num_threads`` (small nets are fastest on 1 thread).
        device: torch device of the policy (``"cpu"``, ``"cuda"``, ``"auto"``; PPO with small MLPs
            is usually fastest on the CPU).
        log_dir: the run's folder: ``progress.csv``, TensorBoard events, checkpoints and evaluations
            go there and nowhere else (None: nothing is written, which needs ``checkpoint_every`` and
            ``eval_every`` None too; stdout only with ``verbose``).
        verbose: SB3 verbosity (1 prints the log table every rollout).
        progress_bar: SB3's progress bar (tqdm + rich) on stderr.
        metrics_window: episodes the logged relocalization rates are taken over.
        checkpoint_every: env steps (summed over envs) between checkpoints
            ``log_dir/checkpoints/ppo_<steps>_steps.zip`` (None: no checkpoints; needs ``log_dir``).
        eval_every: env steps (summed over envs) between evaluations by SB3's ``EvalCallback`` on one
            separate env (None: none; needs ``log_dir``). Logged as ``eval/mean_reward``,
            ``eval/success_rate`` (``info["is_success"]`` at episode end), ...
        eval_episodes: episodes per evaluation.
        eval_seed: seed of the evaluation env (its episodes follow from it, disjoint from training's).
    """

    env_kwargs: dict[str, Any] = field(default_factory=dict)
    env_id: str = ENV_ID
    n_envs: int = 4
    vec_env: str = "dummy"
    workers: int = 1
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
    device: str = "cpu"
    log_dir: str | None = None
    verbose: int = 0
    progress_bar: bool = False
    metrics_window: int = 100
    checkpoint_every: int | None = None
    eval_every: int | None = None
    eval_episodes: int = 5
    eval_seed: int = 10_000

    def __post_init__(self) -> None:
        if self.vec_env not in VEC_ENVS:
            raise ValueError(f"vec_env must be one of {list(VEC_ENVS)}, got {self.vec_env!r}")
        from semreloc_env import semreloc_ids_since

        trainable = semreloc_ids_since(0)  # a SemSlam env takes other arguments
        if self.env_id not in trainable:
            raise ValueError(f"env_id must be one of {list(trainable)}, got {self.env_id!r}")
        positive = ("n_envs", "workers", "total_timesteps", "n_steps", "batch_size", "n_epochs", "torch_threads")
        positive += ("eval_episodes", "metrics_window")
        for name in positive:  # ints, not floats: SB3 and torch fail late on a float count, without naming it
            v = getattr(self, name)
            if not is_int(v) or v < 1:
                raise ValueError(f"{name} must be an int >= 1, got {v!r}")
            object.__setattr__(self, name, int(v))
        for name in ("seed", "eval_seed", "verbose"):
            v = getattr(self, name)
            if not is_int(v) or v < 0:
                raise ValueError(f"{name} must be an int >= 0, got {v!r}")
            object.__setattr__(self, name, int(v))
        if not isinstance(self.progress_bar, (bool, np.bool_)):
            raise ValueError(f"progress_bar must be a bool, got {self.progress_bar!r}")
        for name in ("checkpoint_every", "eval_every"):
            every = getattr(self, name)
            if every is None:
                continue
            if not is_int(every) or every < 1:
                raise ValueError(f"{name} must be None or an int >= 1, got {every!r}")
            object.__setattr__(self, name, int(every))
            if self.log_dir is None:
                raise ValueError(f"{name} needs a log_dir to write to")
        if not is_int(self.workers):
            raise ValueError(f"workers must be an int >= 1, got {self.workers!r}")
        if self.workers > 1 and self.vec_env != "batched":
            raise ValueError(
                f"workers > 1 needs vec_env 'batched' (got {self.vec_env!r}; 'subproc' is a process per env already)"
            )
        if self.workers > self.n_envs:
            raise ValueError(f"workers must be at most n_envs ({self.n_envs}), got {self.workers}")
        check_ppo_settings(self)

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def make_env(
    env_kwargs: dict[str, Any] | None = None,
    belief: bool = True,
    env_id: str = ENV_ID,
    belief_bounds: dict[str, float] | None = None,
) -> gym.Env:
    """``gym.make(env_id, **env_kwargs)``, wrapped in `BeliefObservation` (with ``belief_bounds``, its
    keyword arguments, if given) when ``belief``."""
    env = gym.make(env_id, **dict(env_kwargs or {}))
    return BeliefObservation(env, **dict(belief_bounds or {})) if belief else env


def belief_bounds_of(space: gym.spaces.Space) -> dict[str, float] | None:
    """The `BeliefObservation` keyword arguments that give ``space``'s ``belief`` bounds (None if it has
    no such entry). The default entropy bound is ``log`` of the particle count, so a model trained with
    one count observes another count's env through these (its entropies clipped to its bound)."""
    box = space.spaces.get("belief") if isinstance(space, gym.spaces.Dict) else None
    if not isinstance(box, gym.spaces.Box) or box.shape != (6,):
        return None
    high = box.high.astype(np.float64)
    return {"pos_std_max_m": float(high[0]), "entropy_max_nats": float(high[2]), "max_clusters": float(high[3])}


def make_venv(config: TrainConfig, n_envs: int | None = None, seed: int | None = None):
    """The training ``VecEnv`` of ``config``: env ``k`` seeded ``seed + k``, each in SB3's ``Monitor``.

    ``n_envs`` / ``seed`` default to ``config.n_envs`` / ``config.seed``; the evaluation env is the same
    kind with one env seeded ``config.eval_seed``, but for a ``"subproc"`` config a ``DummyVecEnv`` and for a
    batched one in ``workers`` processes the batched env in this process: one env needs no process (`train` asks for
    that, and silences SB3's ``EvalCallback`` warning that the kinds differ). ``workers`` beyond ``n_envs`` are not
    started.
    """
    env_kwargs = dict(config.env_kwargs)
    n_envs = config.n_envs if n_envs is None else n_envs
    seed = config.seed if seed is None else seed
    if config.vec_env == "batched":
        from stable_baselines3.common.monitor import Monitor

        from .worker_vec_env import WorkersVecEnv, batched_block

        def wrapper(e):
            return Monitor(BeliefObservation(e))

        make_block = batched_block(config.env_id, wrapper, **env_kwargs)
        workers = min(int(config.workers), n_envs)
        venv = WorkersVecEnv(make_block, n_envs, workers) if workers > 1 else make_block(n_envs, 0)
        venv.seed(seed)
        return venv
    return make_vec_env(
        lambda: make_env(env_kwargs, env_id=config.env_id),
        n_envs=n_envs,
        seed=seed,
        vec_env_cls=VEC_ENVS[config.vec_env],
    )


def train(config: TrainConfig, callbacks: Sequence[BaseCallback] = ()) -> PPO:
    """Train PPO as ``config`` says and return the model.

    A `RelocalizationMetricsCallback` always runs (its keys appear in the
    log, ``log_dir/progress.csv`` and TensorBoard), plus SB3's ``CheckpointCallback`` and
    ``EvalCallback`` when ``config.checkpoint_every`` / ``config.eval_every`` are set, plus
    ``callbacks``. The logger is closed when learning ends (or fails); the model's env is left open,
    ``model.get_env().close()`` releases it (a run that fails closes it).
    """
    torch.set_num_threads(int(config.torch_threads))
    venv = make_venv(config)
    try:  # a run that fails closes its envs (subprocesses, workers): the caller has no model to close them by
        model = PPO(
            SemRelocPolicy,
            venv,
            **ppo_hyperparameters(config),
            policy_kwargs={
                "features_extractor_class": SemRelocExtractor,
                "features_extractor_kwargs": {"features_dim": config.features_dim},
                "net_arch": list(config.net_arch),
            },
            seed=config.seed,
            device=config.device,
            verbose=config.verbose,
        )
        if config.log_dir is not None:
            logger = configure(config.log_dir, log_formats(config.verbose))
        else:
            # configure(None, ...) would make an empty folder under the temp dir for every run.
            logger = Logger(None, [HumanOutputFormat(sys.stdout)] if config.verbose else [])
        model.set_logger(logger)
        cbs: list[BaseCallback] = [RelocalizationMetricsCallback(window=config.metrics_window)]
        eval_venv = None
        if config.checkpoint_every is not None:
            cbs.append(
                CheckpointCallback(
                    save_freq=max(1, config.checkpoint_every // config.n_envs),
                    save_path=str(Path(config.log_dir) / "checkpoints"),
                    name_prefix="ppo",
                )
            )
        if config.eval_every is not None:
            eval_kind = dataclasses.replace(config, vec_env="dummy") if config.vec_env == "subproc" else config
            eval_venv = make_venv(eval_kind, n_envs=1, seed=config.eval_seed)
            eval_dir = str(Path(config.log_dir) / "eval")
            cbs.append(
                EvalCallback(
                    eval_venv,
                    n_eval_episodes=config.eval_episodes,
                    eval_freq=max(1, config.eval_every // config.n_envs),
                    log_path=eval_dir,
                    best_model_save_path=eval_dir,
                    deterministic=True,
                    verbose=config.verbose,
                )
            )
        cbs.extend(callbacks)
        try:
            with warnings.catch_warnings():
                # the evaluation env is one robot in this process by design (make_venv), also for "subproc" and workers
                warnings.filterwarnings("ignore", message="Training and eval env are not of the same type")
                bar = progress_bar_wanted(config.progress_bar)
                model.learn(total_timesteps=config.total_timesteps, callback=cbs, progress_bar=bar)
        finally:
            logger.close()
            if eval_venv is not None:
                eval_venv.close()
    except BaseException:
        close_after_interrupt(venv)
        raise
    return model


def _as_action_fn(
    model_or_policy: Any, deterministic: bool, seed: int = 0
) -> tuple[Callable[[dict], Any], Callable[[], None]]:
    if isinstance(model_or_policy, BaseAlgorithm):
        # a model trained under VecNormalize sees observations as it did in training: normalised by its statistics
        vec_normalize = model_or_policy.get_vec_normalize_env()
        seen = (lambda obs: obs) if vec_normalize is None else vec_normalize.normalize_obs
        if deterministic:

            def act(obs: dict):
                action, _ = model_or_policy.predict(seen(obs), deterministic=True)
                return action

        else:  # drawn from a generator of its own, not torch's global one (as predict samples)
            from .learned import check_samplable, sample_action

            check_samplable(model_or_policy)
            rng = np.random.default_rng(seed)

            def act(obs: dict):
                return sample_action(model_or_policy, seen(obs), rng)

        return act, lambda: None
    if not callable(model_or_policy):
        hint = ""
        if hasattr(model_or_policy, "wrap") and hasattr(model_or_policy, "act"):  # agents.policies' interface
            hint = (
                " (a policy of agents.policies, or agents.learned.load_policy's of a train_active run, acts on its own "
                "wrapped env: evaluate it with scripts/evaluate_active.py, agents.experiments.evaluate_active)"
            )
        raise TypeError(
            f"expected an SB3 model or a callable obs -> action, got {type(model_or_policy).__name__}{hint}"
        )
    reset = getattr(model_or_policy, "reset", None)
    return model_or_policy, (reset if callable(reset) else lambda: None)


def env_for(model_or_policy: Any, env_kwargs: dict[str, Any] | None = None, env_id: str = ENV_ID) -> gym.Env:
    """`make_env` for ``model_or_policy``: an SB3 model's env observes the belief with the bounds the model was
    trained with (`belief_bounds_of`, e.g. another particle count).

    Raises:
        ValueError: the model's observation or action space differs from the env's (the entries that differ are
            named); the env is closed then.
    """
    env = make_env(env_kwargs, env_id=env_id)
    if not isinstance(model_or_policy, BaseAlgorithm):
        return env
    model_space = model_or_policy.observation_space
    if model_space != env.observation_space:
        bounds = belief_bounds_of(model_space)
        if bounds is not None:
            env.close()
            env = make_env(env_kwargs, env_id=env_id, belief_bounds=bounds)
    if model_space != env.observation_space or model_or_policy.action_space != env.action_space:
        env.close()
        ours, theirs = env.observation_space, model_space
        keys = sorted(
            k for k in set(getattr(ours, "spaces", {})) | set(getattr(theirs, "spaces", {}))
            if getattr(ours, "spaces", {}).get(k) != getattr(theirs, "spaces", {}).get(k)
        )  # fmt: skip
        if model_or_policy.action_space != env.action_space:
            keys.append(f"actions (model {model_or_policy.action_space}, env {env.action_space})")
        raise ValueError(
            f"the model's observation or actions differ from the env's in {keys or ['its observation type']}: "
            f"evaluate it with the env id and env_kwargs it was trained with (this is {env_id}, env_kwargs "
            f"{dict(env_kwargs or {})}; a policy of scripts/train_active.py runs with scripts/evaluate_active.py)"
        )
    return env


def _one_number(action) -> bool:
    """Whether ``action`` is one real number (a Python or NumPy number or a 0-d numeric array, not a bool): what a
    discrete policy returns."""
    return is_real(action) or (isinstance(action, np.ndarray) and action.ndim == 0 and action.dtype.kind in "iuf")


def evaluate(
    model_or_policy: Any,
    env_kwargs: dict[str, Any] | None = None,
    n_episodes: int = 20,
    seed: int = 0,
    deterministic: bool = True,
    return_episodes: bool = False,
    env_id: str = ENV_ID,
) -> dict[str, Any]:
    """Run ``n_episodes`` episodes of ``model_or_policy`` and summarise them.

    Args:
        model_or_policy: an SB3 model (``BaseAlgorithm``; acts with ``predict``, on observations normalised by
            its ``VecNormalize`` statistics if its env has them: ``model.get_vec_normalize_env()``; for a loaded
            model, ``model.set_env(VecNormalize.load(path, venv))`` first) or a callable
            ``obs dict -> action`` such as `agents.baselines.WallFollowExplorer` (its ``reset()``
            is called at every episode start, if it has one). Callables see the same observation
            as models, including the ``belief`` key.
        env_kwargs: ``gym.make(env_id, ...)`` keyword arguments (``max_episode_steps`` too).
        n_episodes: episodes; episode ``i`` starts with ``reset(seed=seed + i)``.
        seed: first episode seed.
        deterministic: SB3 models act greedily (ignored for callables); False: they sample their actions from
            a generator seeded with ``seed`` (`agents.learned.sample_action`), not from torch's global one.
        return_episodes: add ``"per_episode"``: the list of `EpisodeResult.as_dict`.
        env_id: the env to run (a model trained on ``SemReloc-v1``'s flat observation needs ``"SemReloc-v1"``).

    Returns:
        `agents.metrics.summarize_episodes` of the episodes: ``success_rate``,
        ``wrong_convergence_rate``, ``unconverged_rate``, ``first_convergence_wrong_rate`` in
        ``[0, 1]``, ``median_steps_to_converge`` (steps, None if nothing succeeded), median final
        errors (m, rad), mean length and return. Equal inputs (and a policy in the same state) give
        an equal dict.
    """
    if not is_int(n_episodes) or n_episodes < 1:
        raise ValueError(f"n_episodes must be an int >= 1, got {n_episodes!r}")
    if not is_int(seed) or seed < 0:
        raise ValueError(f"seed must be an int >= 0, got {seed!r}")
    env = env_for(model_or_policy, env_kwargs, env_id)
    act, reset_policy = _as_action_fn(model_or_policy, deterministic, seed)
    discrete = isinstance(env.action_space, gym.spaces.Discrete)
    from_model = isinstance(model_or_policy, BaseAlgorithm)  # predict's arrays; a callable's actions go as given
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
                if from_model and discrete:
                    action = int(action)
                try:
                    obs, reward, terminated, truncated, info = env.step(action)
                except ValueError as e:  # the env refused the action and changed nothing
                    if not discrete and _one_number(action):
                        raise ValueError(
                            f"{e}; the policy returned one number, a discrete action, and this env's actions are "
                            "(v, omega) pairs (action_type='continuous'): evaluate a policy for continuous actions"
                        ) from None
                    raise
                tracker.observe(info, reward)
                done = terminated or truncated
            results.append(tracker.finish())
    finally:
        env.close()
    summary: dict[str, Any] = summarize_episodes(results)
    if return_episodes:
        summary["per_episode"] = [r.as_dict() for r in results]
    return summary
