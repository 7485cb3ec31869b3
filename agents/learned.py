"""Trained active-relocalization policies behind the baselines' interface.

* `save_policy` writes an SB3 model zip with one more member, ``semreloc_policy.json``:
  what the policy needs around it (the `ActiveObservation`
  settings, the action repeat and the motion options it was trained with).
* `load_policy` reads such a file and returns a `LearnedPolicy` with
  ``wrap(env) -> env`` (applies the same observation wrapper to any ``SemReloc`` env, any layout
  and particle count), ``reset()`` and ``act(obs) -> action`` (deterministic), exactly as the
  baselines of `agents.policies`.

A policy trained through `semreloc_env.wrappers.ActionRepeat` decides every ``repeat``
env steps; `LearnedPolicy.act` is called every step and holds its last decision in
between, so an evaluation loop drives it like any other policy and sees the same observations
at the decision steps as training did.
"""

from __future__ import annotations

import contextlib
import json
import pickle
import zipfile
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from filters.numbers import is_int
from semreloc_env.envs.spaces import require_raw_observation, require_single_env
from semreloc_env.observations import ActiveObservation
from semreloc_env.wrappers import ActionRepeat, find_wrapper

META_NAME = "semreloc_policy.json"
"""Name of the metadata member inside a saved policy zip."""

FORMAT_VERSION = 1

SHIPPED_POLICY = Path(__file__).resolve().parent / "data" / "active_ppo.zip"
"""The trained active-relocalization policy shipped with the package (docs/active.md says how it
was trained and how it scores): ``load_policy(SHIPPED_POLICY)``."""


def save_policy(
    model,
    path: str | Path,
    observation: dict[str, Any],
    repeat: int,
    explorer_option: bool = False,
    extra: dict | None = None,
    options: tuple[str, ...] | None = None,
) -> Path:
    """Save ``model`` (an SB3 algorithm) to ``path`` (``.zip`` added if missing) with its metadata.

    Args:
        observation: keyword arguments of `ActiveObservation` the model was trained with.
        repeat: env steps per decision (`semreloc_env.wrappers.ActionRepeat`).
        explorer_option: whether it acts through `agents.options.ExplorerOption` (the same as
            ``options=("explore",)``).
        extra: anything else worth keeping beside it (training config, env id, ...): JSON-able.
        options: the `agents.options.MotionOptions` it acts through (None: none, or the explorer
            with ``explorer_option``).

    Returns:
        The path written.
    """
    check_no_vec_normalize(model)
    path = Path(path)
    if path.suffix != ".zip":
        path = path.with_suffix(".zip")
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)
    options = option_names(options, explorer_option)
    meta = {
        "format": FORMAT_VERSION,
        "algorithm": type(model).__name__,
        "observation": dict(observation),
        "repeat": int(repeat),
        "explorer_option": options == ("explore",),
        "options": list(options),
        "extra": extra or {},
    }
    with zipfile.ZipFile(path, "a") as z:
        z.writestr(META_NAME, json.dumps(meta, indent=1, default=str))
    return path


def check_no_vec_normalize(model) -> None:
    """ValueError if ``model`` trains through SB3's ``VecNormalize``: a saved policy and `LearnedPolicy` act on the
    env's raw observations, and the normalisation's statistics are not part of the model, so such a policy would
    act on inputs it never saw. (`agents.train.evaluate` handles ``VecNormalize`` for `agents.train`'s models.)"""
    get = getattr(model, "get_vec_normalize_env", None)
    if get is not None and get() is not None:
        raise ValueError(
            "the model trains through VecNormalize, whose statistics a saved policy would not keep (it acts on raw "
            "observations): train without VecNormalize (ActiveObservation's entries are scaled already), or act "
            "with model.predict(vec_normalize.normalize_obs(obs)) yourself"
        )


class MissingMetadataError(ValueError):
    """A zip without `save_policy`'s metadata member: a bare SB3 checkpoint, or another program's model."""


def read_metadata(path: str | Path) -> dict[str, Any]:
    """The metadata of a policy saved by `save_policy`.

    Raises:
        FileNotFoundError: no such file.
        ValueError: not a zip, or a zip without the metadata member (`MissingMetadataError`, e.g. a bare SB3
            checkpoint: pass ``observation`` and ``repeat`` to `load_policy` then).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no policy file {path}")
    try:
        with zipfile.ZipFile(path) as z:
            if META_NAME not in z.namelist():
                raise MissingMetadataError(
                    f"{path} has no {META_NAME}: not saved by agents.learned.save_policy. A bare checkpoint in the "
                    "checkpoints/ folder of a train_active run loads with load_policy(path), which reads the run's "
                    "config.json; one kept elsewhere loads with its settings given, "
                    "load_policy(path, observation={...}, repeat=N) (the "
                    "run's --config.observation and --config.repeat); agents.learned.save_policy(policy.model, "
                    "'mine.zip', observation={...}, repeat=N, options=(...)) then makes a file any tool loads. A "
                    "model of scripts/train_ppo.py is no such policy (it sees BeliefObservation's vector): "
                    "evaluate it with `train_ppo.py --load` or agents.train.evaluate(stable_baselines3.PPO.load(path), "
                    "env_kwargs)"
                )
            meta = json.loads(z.read(META_NAME))
    except zipfile.BadZipFile as e:
        raise ValueError(f"{path} is not a policy zip: {e}") from e
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise ValueError(f"{path}: {META_NAME} is not valid JSON: {e}") from e
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: {META_NAME} must hold a JSON object, got {type(meta).__name__}")
    if meta.get("format") != FORMAT_VERSION:
        raise ValueError(f"{path}: policy format {meta.get('format')!r}, this code reads {FORMAT_VERSION}")
    missing = [k for k in ("observation", "repeat") if k not in meta]
    if missing:
        raise ValueError(f"{path}: {META_NAME} lacks {missing}")
    return meta


def option_names(options, explorer_option: bool) -> tuple[str, ...]:
    """The option names: ``options`` if given, else the explorer alone if ``explorer_option`` (how runs
    saved before ``options`` existed record them)."""
    if options is None:
        return ("explore",) if explorer_option else ()
    return tuple(str(o) for o in options)


def run_folder_of(checkpoint: Path) -> Path:
    """The run folder a checkpoint belongs to (``<out>/checkpoints/x.zip`` or ``<out>/policy.zip``)."""
    return checkpoint.parent.parent if checkpoint.parent.name == "checkpoints" else checkpoint.parent


def saved_settings(path: str | Path) -> dict[str, Any]:
    """How the policy file ``path`` was trained, as far as it or its run folder says: `save_policy`'s
    metadata, or for a bare checkpoint in a training run's ``checkpoints/``, the ``observation`` and
    ``repeat`` of the run's ``config.json`` (what `load_policy` needs no argument for).

    Raises:
        FileNotFoundError: no such file.
        ValueError: neither (see `read_metadata`).
    """
    path = Path(path)
    try:
        return read_metadata(path)
    except MissingMetadataError:
        saved = saved_run_config(path) if path.parent.name == "checkpoints" else None
        if saved is None or not {"observation", "repeat"} <= saved.keys():
            raise
        return {k: saved[k] for k in ("observation", "repeat")}


def saved_run_config(checkpoint: Path) -> dict[str, Any] | None:
    """The training config in the ``config.json`` of a checkpoint's run folder (`run_folder_of`): a
    ``train_active`` run's, an imitation run's ``train`` entry or a ``train_ppo`` run's ``config``
    entry; None without such a file."""
    f = run_folder_of(checkpoint) / "config.json"
    if not f.is_file():
        return None
    saved = json.loads(f.read_text())
    return saved.get("train", saved.get("config", saved))


class LearnedPolicy:
    """A trained SB3 model with the interface of `agents.policies`.

    Args:
        model: an SB3 algorithm whose observation space is `ActiveObservation`'s.
        observation: the `ActiveObservation` keyword arguments it was trained with.
        repeat: env steps per decision.
        deterministic: act on the mode of the action distribution (default) or sample from it.
        explorer_option: the model's actions are `agents.options.ExplorerOption`'s (the env's
            four and "explore"); `wrap` adds that wrapper.
        seed: with ``deterministic=False``, the seed of the policy's own generator of action draws
            (`numpy.random.Generator`), which `reset` starts afresh, so an episode's actions depend
            neither on the episodes before it nor on other code in the process (torch's, NumPy's and
            Python's global streams are neither used nor reseeded).
        options: the model's actions are `agents.options.MotionOptions` over these names
            (overrides ``explorer_option``); `wrap` adds that wrapper.

    Call `reset` at every episode start: it also drops the decision being held.
    """

    def __init__(
        self,
        model,
        observation: dict[str, Any],
        repeat: int = 1,
        deterministic: bool = True,
        explorer_option: bool = False,
        seed: int = 0,
        options: tuple[str, ...] | None = None,
    ):
        if not is_int(repeat) or repeat < 1:
            raise ValueError(f"repeat must be an integer >= 1, got {repeat!r}")
        check_no_vec_normalize(model)
        self.model = model
        self.observation = dict(observation)
        self.repeat = int(repeat)
        self.deterministic = bool(deterministic)
        self.options = option_names(options, explorer_option)
        self.explorer_option = self.options == ("explore",)
        self.seed = int(seed)
        if not self.deterministic:
            check_samplable(model)
        self._rng = np.random.default_rng(self.seed)
        self._t = 0
        self._action = None

    def wrap(self, env: gym.Env) -> gym.Env:
        """``ActiveObservation(env, **observation)`` (over `agents.options.MotionOptions` when
        the policy uses options), checked against the model's spaces. A policy of discrete actions
        also runs on an env with continuous actions (`agents.options.MotionOptions` sends its
        choices as ``(v, omega)``; the planner option's steps drive arcs).

        Raises:
            ValueError: the env's action space or the wrapped observation space differs from the
                model's (another action type, camera or lidar beam count, ...), or the env repeats
                actions already (`semreloc_env.wrappers.ActionRepeat`: `act` holds each decision
                for ``repeat`` env steps itself, so the two would multiply).
            TypeError: a vector env (one policy per env).
        """
        require_single_env(env, "a learned policy")
        repeating = find_wrapper(env, ActionRepeat)
        if repeating is not None:
            raise ValueError(
                f"the env is wrapped by ActionRepeat(repeat={repeating.repeat}); the policy holds each decision for "
                f"{self.repeat} env step(s) itself, so each would last {repeating.repeat * self.repeat}: pass the env "
                "without ActionRepeat"
            )
        require_raw_observation(env, "a learned policy")  # before the action check: an env wrap() returned fails here
        discrete_model = isinstance(self.model.action_space, spaces.Discrete)
        if self.options or (discrete_model and isinstance(env.action_space, spaces.Box)):
            from .options import MotionOptions, has_semreloc_actions

            if not has_semreloc_actions(env.action_space):
                raise ValueError(
                    f"the env's action space {env.action_space} is neither Discrete(4) nor Box(-1, 1, (2,)), "
                    "one of which the policy needs"
                )
            env = MotionOptions(env, self.options)
        if env.action_space != self.model.action_space:
            raise ValueError(f"the env's action space {env.action_space} is not the policy's {self.model.action_space}")
        wrapped = ActiveObservation(env, **self.observation)
        if wrapped.observation_space != self.model.observation_space:
            raise ValueError(
                "the wrapped env's observation space differs from the policy's (sensor beam counts?): "
                + _space_difference(wrapped.observation_space, self.model.observation_space)
            )
        return wrapped

    def reset(self) -> None:
        """Start an episode: the next `act` decides afresh."""
        self._t = 0
        self._action = None
        self._rng = np.random.default_rng(self.seed)

    def act(self, obs: dict):
        """The action for this step: a new decision every ``repeat`` steps, else the held one."""
        if self._t % self.repeat == 0 or self._action is None:
            space = self.model.observation_space
            if isinstance(space, spaces.Dict) and not (isinstance(obs, dict) and set(space.spaces) <= set(obs)):
                missing = sorted(set(space.spaces) - set(obs)) if isinstance(obs, dict) else list(space.spaces)
                raise ValueError(
                    f"observation lacks {missing}: act on the observations of the env policy.wrap(env) returned"
                )
            if self.deterministic:
                action, _ = self.model.predict(obs, deterministic=True)
            else:
                action = sample_action(self.model, obs, self._rng)
            self._action = int(action) if isinstance(self.model.action_space, spaces.Discrete) else np.asarray(action)
        self._t += 1
        return self._action


def _squashed_actor(policy):
    """SAC's actor (a tanh-squashed diagonal Gaussian, ``get_action_dist_params``), or None."""
    actor = getattr(policy, "actor", None)
    return actor if hasattr(actor, "get_action_dist_params") else None


def check_samplable(model) -> None:
    """ValueError unless `sample_action` can draw ``model``'s actions: a policy with an action distribution
    (PPO's and A2C's, SAC's squashed Gaussian; DQN's and TD3's have none) and no state-dependent exploration
    (``use_sde``, whose noise `sample_action` does not draw)."""
    if not (hasattr(model.policy, "get_distribution") or _squashed_actor(model.policy) is not None):
        raise ValueError(
            f"sampling draws from the model's action distribution; a {type(model).__name__} policy has none: "
            "use deterministic=True"
        )
    if getattr(model, "use_sde", False):
        raise ValueError(
            "a model trained with state-dependent exploration (use_sde) cannot sample from the policy's own "
            "generator: use deterministic=True"
        )


def sample_action(model, obs, rng: np.random.Generator):
    """One action drawn from ``model``'s action distribution at ``obs`` with ``rng`` (not torch's global
    generator, which SB3's ``predict`` samples with): a categorical's by its probabilities (one draw per
    dimension of a ``MultiDiscrete``), a diagonal Gaussian's as ``mean + std * normal``, clipped to the
    action space's bounds as ``predict`` clips, SAC's squashed Gaussian as ``tanh(mean + std * normal)`` scaled to the
    bounds as ``predict`` scales it. ValueError for another distribution (use ``deterministic=True``)."""
    import torch
    from stable_baselines3.common.distributions import (
        CategoricalDistribution,
        DiagGaussianDistribution,
        MultiCategoricalDistribution,
    )

    policy = model.policy
    policy.set_training_mode(False)  # as predict does
    obs_t, _ = policy.obs_to_tensor(obs)
    actor = None if hasattr(policy, "get_distribution") else _squashed_actor(policy)
    if actor is not None:
        with torch.no_grad():
            mean, log_std, _ = actor.get_action_dist_params(obs_t)
        mean = mean[0].cpu().numpy().astype(np.float64)
        std = np.exp(log_std[0].cpu().numpy().astype(np.float64))
        squashed = np.tanh(mean + std * rng.standard_normal(mean.shape))
        return policy.unscale_action(squashed).astype(model.action_space.dtype)
    with torch.no_grad():
        dist = policy.get_distribution(obs_t)
    if isinstance(dist, (CategoricalDistribution, MultiCategoricalDistribution)):
        parts = dist.distribution if isinstance(dist, MultiCategoricalDistribution) else [dist.distribution]
        picks = []
        for part in parts:
            p = part.probs[0].cpu().numpy().astype(np.float64)
            cdf = np.cumsum(p / p.sum())
            picks.append(min(int(np.searchsorted(cdf, rng.random(), side="right")), p.size - 1))
        return picks[0] if isinstance(dist, CategoricalDistribution) else np.array(picks, dtype=np.int64)
    if isinstance(dist, DiagGaussianDistribution):
        mean = dist.distribution.mean[0].cpu().numpy().astype(np.float64)
        std = dist.distribution.stddev[0].cpu().numpy().astype(np.float64)
        a = mean + std * rng.standard_normal(mean.shape)
        space = model.action_space
        return np.clip(a, space.low, space.high).astype(space.dtype)
    raise ValueError(f"sampling a {type(dist).__name__} is not supported: use deterministic=True")


def _space_difference(env_space: spaces.Space, policy_space: spaces.Space) -> str:
    """What differs between two observation spaces, entry by entry for ``Dict`` spaces (short)."""

    def brief(s) -> str:
        shape = getattr(s, "shape", None)
        return f"{type(s).__name__}{tuple(shape) if shape is not None else ''}"

    if not (isinstance(env_space, spaces.Dict) and isinstance(policy_space, spaces.Dict)):
        return f"env {brief(env_space)}, policy {brief(policy_space)}"
    parts = []
    for k in sorted(set(env_space.spaces) | set(policy_space.spaces)):
        e, p = env_space.spaces.get(k), policy_space.spaces.get(k)
        if e is None or p is None:
            parts.append(f"'{k}' only in the {'policy' if e is None else 'env'}'s")
        elif e != p:
            same = brief(e) == brief(p)
            parts.append(f"'{k}': env {brief(e)}, policy {brief(p)}" + (" (other bounds)" if same else ""))
    return "; ".join(parts)


def _checkpoint_options(path: Path, action_space) -> tuple[str, ...]:
    """The motion options of a bare SB3 checkpoint: from its run's ``config.json`` (``train_active``
    writes checkpoints to ``<out>/checkpoints/``), else by its action count (5: the explorer)."""
    n = int(action_space.n) if isinstance(action_space, spaces.Discrete) else 4
    saved = saved_run_config(path) if path.parent.name == "checkpoints" else None
    if saved is not None:
        found = option_names(saved.get("options"), saved.get("explorer_option", False))
        if 4 + len(found) == n:
            return found
    if n <= 5:
        return ("explore",) * (n - 4)
    raise ValueError(
        f"{path}: a checkpoint with {n} actions and no record of its motion options; "
        "pass options=(...) in the order the run used (see its config.json)"
    )


ALGORITHMS = ("PPO", "A2C", "DQN", "SAC", "TD3", "DDPG")
"""The stable-baselines3 algorithms `load_model` (and so `load_policy`) loads, by class name."""


@contextlib.contextmanager
def kept_global_rngs():
    """Restore the states of Python's ``random``, NumPy's global generator and torch's CPU generator on leaving: what
    runs inside may reseed them (SB3's ``load`` does), the caller's draws go on as if it had not run."""
    import random

    import torch

    py, np_state = random.getstate(), np.random.get_state()  # noqa: NPY002 - the global state is what is kept
    with torch.random.fork_rng(devices=[]):
        try:
            yield
        finally:
            random.setstate(py)
            np.random.set_state(np_state)  # noqa: NPY002


def load_model(path: str | Path, algorithm: str = "PPO", device: str = "cpu", env=None):
    """The stable-baselines3 ``algorithm`` model (a name of `ALGORITHMS`) saved in ``path``, on ``device``,
    with ``env`` attached if given.

    Raises:
        ValueError: ``algorithm`` is not one of `ALGORITHMS`, or ``path`` is not a model of it (another
            algorithm's, a damaged file, a zip of something else).
    """
    if algorithm not in ALGORITHMS:
        raise ValueError(
            f"{path}: algorithm {algorithm!r} is none of stable-baselines3's {list(ALGORITHMS)}; load the model "
            "yourself and wrap it: agents.learned.LearnedPolicy(model, observation={...}, repeat=N)"
        )
    import stable_baselines3

    try:
        with kept_global_rngs():  # SB3's load reseeds Python's, NumPy's and torch's global generators
            return getattr(stable_baselines3, algorithm).load(path, env=env, device=device)
    except (AssertionError, AttributeError, EOFError, KeyError, TypeError, ValueError, RuntimeError,
            zipfile.BadZipFile, pickle.UnpicklingError) as e:  # fmt: skip
        raise ValueError(f"{path}: not a loadable stable-baselines3 {algorithm} model ({type(e).__name__}: {e})") from e


def load_policy(
    path: str | Path,
    device: str = "cpu",
    deterministic: bool = True,
    observation: dict[str, Any] | None = None,
    repeat: int | None = None,
    explorer_option: bool | None = None,
    seed: int = 0,
    options: tuple[str, ...] | None = None,
) -> LearnedPolicy:
    """Load a policy saved by `save_policy` (or a bare SB3 PPO checkpoint, given its settings). The model loads
    with the stable-baselines3 class its metadata names (``"algorithm"``: PPO, A2C, DQN, SAC, TD3 or DDPG; a
    bare checkpoint: PPO).

    Args:
        path: the ``.zip``.
        device: torch device to load onto.
        deterministic: see `LearnedPolicy`.
        observation: override (or, for a checkpoint without metadata, supply) the
            `ActiveObservation` settings; a checkpoint without metadata in a training run's
            ``checkpoints/`` takes them from the run's ``config.json`` unless given.
        repeat: the same for the action repeat (an override that differs from the training's
            changes how long each decision is held: the policy then runs as it was not trained).
        explorer_option: the same for `agents.options.ExplorerOption` (without metadata:
            True when the model has five discrete actions, as `train_active`'s checkpoints do).
        seed: see `LearnedPolicy`.
        options: the same for `agents.options.MotionOptions` (overrides ``explorer_option``;
            without metadata: from the training run's ``config.json`` when ``path`` is one of its
            ``checkpoints/``, else the explorer for a model with five discrete actions).

    Raises:
        FileNotFoundError, ValueError: see `read_metadata`; ValueError also when the options of a
            bare checkpoint with more than five actions cannot be known (pass ``options``), when the
            model does not load (`load_model`) and when ``device`` is none this machine has.
    """
    path = Path(path)
    if observation is None or repeat is None or (explorer_option is None and options is None):
        try:
            meta = saved_settings(path)
        except ValueError:
            if observation is None or repeat is None:
                raise
            meta = {}
        observation = meta["observation"] if observation is None else observation
        repeat = meta["repeat"] if repeat is None else repeat
        if options is None and explorer_option is None and "options" in meta:
            options = tuple(meta["options"])
        if explorer_option is None and "explorer_option" in meta:
            explorer_option = bool(meta["explorer_option"])
    if not Path(path).is_file():
        raise FileNotFoundError(f"no policy file {path}")
    from .train import check_device  # imported here, as PPO is: torch only when a policy is loaded

    check_device(device)
    try:
        algorithm = read_metadata(path).get("algorithm", "PPO")
    except ValueError:  # a bare checkpoint: train_active's and train_ppo's are PPO's
        algorithm = "PPO"
    model = load_model(path, algorithm, device)
    if options is None and explorer_option is None:
        options = _checkpoint_options(path, model.action_space)
    return LearnedPolicy(model, observation, repeat, deterministic, bool(explorer_option), seed, options)
