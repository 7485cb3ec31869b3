"""Observation variants of the semreloc envs, as wrappers (Minigrid ``FlatObsWrapper`` style).

* `BeliefObservation` adds a ``belief`` key: a few numbers summarising what the
  relocalizer *believes* (spread, entropy, hypotheses, degeneracy, converged), read from
  ``info["belief"]`` (`filters.localization.belief.Belief.as_dict`). It never exposes the true pose
  nor the pose error: a policy that sees them would be cheating.
* `ActiveObservation` (from `semreloc_env.observations`) replaces the observation
  by what an active-relocalization policy needs: egocentric and whole-map images of the belief,
  the map and its classes, the hypothesis list, normalised scans and the last action, with
  bounds independent of the particle count and the layout size.
* `FlatObservation` concatenates every key of a Dict observation into one float32 Box,
  for algorithms and networks that want a flat vector.
* `CheckedReset` is the outermost wrapper of the registered envs: it checks the reset
  arguments before Gymnasium's ``TimeLimit`` (which zeroes its step counter first) sees them.
* `ResetOptions` merges given reset options into every reset's (the call's entries win): a training
  run's look-alike kidnappings, for instance, since SB3's vec envs reset without options.

Typical use::

    env = FlatObservation(BeliefObservation(gym.make("SemReloc-v2")))
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from filters.numbers import is_int, is_real

BELIEF_FEATURES = ("pos_std_m", "theta_std_rad", "entropy_nats", "n_clusters", "ess_frac", "converged")
"""Order of the entries of the ``belief`` observation (see `BeliefObservation`)."""


class BeliefObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Add the filter's belief summary to the Dict observation under the key ``belief``.

    ``obs["belief"]`` is a float32 vector of ``len(BELIEF_FEATURES)`` = 6 entries, each
    taken from the ``info["belief"]`` of the same ``reset`` / ``step`` and clipped to its bounds:

    | index | name | unit | bounds | from ``info["belief"]`` |
    |---|---|---|---|---|
    | 0 | ``pos_std_m`` | m | ``[0, pos_std_max_m]`` | ``pos_std_m`` (``sqrt(var_x + var_y)``) |
    | 1 | ``theta_std_rad`` | rad | ``[0, pi]`` | ``theta_std_rad`` (wrapped residuals, so <= pi) |
    | 2 | ``entropy_nats`` | nats | ``[0, entropy_max_nats]`` | ``entropy_nats`` (coarse pose histogram) |
    | 3 | ``n_clusters`` | count | ``[0, max_clusters]`` | ``n_clusters`` (position hypotheses) |
    | 4 | ``ess_frac`` | 1 | ``[0, 1]`` | ``ess / n_particles`` (1 = no degeneracy) |
    | 5 | ``converged`` | 0/1 | ``[0, 1]`` | ``converged`` |

    Clipping only bites beyond the bounds, which the defaults make rare: the entropy of a
    histogram of N particles is at most ``log N``, and the default ``entropy_max_nats`` is the
    log of the relocalizer's particle budget (clustered resampling and the audit can take a set
    somewhat above it, up to about 1.8 times at budgets of 100 to 1000: ``log 1.8`` = 0.6 nats more at most; an
    audit adds 50 particles whatever the budget, so below about 60 pass ``entropy_max_nats`` yourself).

    The wrapped env must put ``belief`` in ``info`` at every reset and step (``SemReloc-v2``
    does); a `SemSlam` env is refused with ``TypeError``, and a missing key at a reset or step raises a
    ``KeyError`` that names the keys the info has. Rewards, termination and ``info`` pass through
    unchanged.

    Args:
        env: an env with a ``Dict`` observation space and ``info["belief"]``.
        pos_std_max_m: upper bound of ``pos_std_m`` (default 20 m, beyond the half-diagonal of
            the built-in layouts).
        entropy_max_nats: upper bound of ``entropy_nats``; default ``log`` of the relocalizer's
            largest particle count (``n_particles``, or ``max_particles`` when it is None),
            read from ``env.unwrapped.mcl_config``, or ``log(10_000)`` if the env has none.
        max_clusters: upper bound of ``n_clusters`` (default 20).
    """

    def __init__(
        self,
        env: gym.Env,
        pos_std_max_m: float = 20.0,
        entropy_max_nats: float | None = None,
        max_clusters: int = 20,
    ):
        gym.utils.RecordConstructorArgs.__init__(
            self, pos_std_max_m=pos_std_max_m, entropy_max_nats=entropy_max_nats, max_clusters=max_clusters
        )
        gym.Wrapper.__init__(self, env)
        if not isinstance(env.observation_space, spaces.Dict):
            raise TypeError(f"BeliefObservation needs a Dict observation space, got {env.observation_space}")
        if "belief" in env.observation_space.spaces:
            raise ValueError("the observation already has a 'belief' key")
        from semreloc_env.envs.semslam import SemSlamEnv

        if isinstance(env.unwrapped, SemSlamEnv):  # its info holds a map estimate, no belief
            raise TypeError("BeliefObservation needs a SemReloc env (info['belief']); SemSlamEnv has no belief")
        if entropy_max_nats is None:
            cfg = getattr(env.unwrapped, "mcl_config", None)
            n_max = 10_000
            if cfg is not None:
                n_max = int(cfg.max_particles) if cfg.n_particles is None else int(cfg.n_particles)
            entropy_max_nats = math.log(max(n_max, 2))
        for name, v in (
            ("pos_std_max_m", pos_std_max_m),
            ("entropy_max_nats", entropy_max_nats),
            ("max_clusters", max_clusters),
        ):
            if not (is_real(v) and math.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
        self.belief_low = np.zeros(len(BELIEF_FEATURES), dtype=np.float32)
        self.belief_high = np.array(
            [pos_std_max_m, math.pi, entropy_max_nats, max_clusters, 1.0, 1.0], dtype=np.float32
        )
        self.observation_space = spaces.Dict(
            {
                **env.observation_space.spaces,
                "belief": spaces.Box(self.belief_low, self.belief_high, dtype=np.float32),
            }
        )

    def belief_features(self, belief: dict) -> np.ndarray:
        """The ``(6,)`` float32 feature vector of an ``info["belief"]`` dict (order: `BELIEF_FEATURES`)."""
        n = max(int(belief["n_particles"]), 1)
        raw = np.array(
            [
                belief["pos_std_m"],
                belief["theta_std_rad"],
                belief["entropy_nats"],
                belief["n_clusters"],
                belief["ess"] / n,
                1.0 if belief["converged"] else 0.0,
            ],
            dtype=np.float32,
        )
        return np.clip(raw, self.belief_low, self.belief_high)

    def _augment(self, obs: dict, info: dict) -> dict:
        if "belief" not in info:
            raise KeyError(
                f"BeliefObservation needs info['belief'] at every reset and step (SemReloc envs give it); "
                f"{type(self.env.unwrapped).__name__}'s info has {sorted(info)}"
            )
        out = dict(obs)
        out["belief"] = self.belief_features(info["belief"])
        return out

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        return self._augment(obs, info), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._augment(obs, info), reward, terminated, truncated, info


class FlatObservation(gym.ObservationWrapper, gym.utils.RecordConstructorArgs):
    """Concatenate the entries of a Dict observation into one float32 Box.

    The flat vector holds the keys in ``keys`` order (default: the Dict's own key order, which
    gymnasium sorts: ``belief, lidar, odometry, semantic_class, semantic_range`` for
    ``BeliefObservation(gym.make("SemReloc-v2"))``). A Box entry is flattened C-order with its own
    bounds, so units and ranges are those of the Dict entry (see the env docstring and
    `BeliefObservation`); a ``MultiDiscrete`` entry (the class labels) is one-hot encoded,
    ``nvec[i]`` entries in ``[0, 1]`` per element, element-major, as stable-baselines3 encodes it.
    ``self.slices[key]`` is where a key sits in the vector.

    Args:
        env: an env with a ``Dict`` observation space of ``Box`` and 1-D ``MultiDiscrete`` entries.
        keys: which keys to keep, in order (default: all).
    """

    def __init__(self, env: gym.Env, keys: Sequence[str] | None = None):
        gym.utils.RecordConstructorArgs.__init__(self, keys=keys)
        gym.ObservationWrapper.__init__(self, env)
        space = env.observation_space
        if not isinstance(space, spaces.Dict):
            raise TypeError(f"FlatObservation needs a Dict observation space, got {space}")
        if isinstance(keys, (str, bytes)):
            raise ValueError(f"keys must be a list of observation keys, got {keys!r:.80} (one key: [{keys!r:.40}])")
        self.keys = tuple(space.spaces) if keys is None else tuple(keys)
        unknown = [k for k in self.keys if k not in space.spaces]
        if unknown:
            raise KeyError(f"keys {unknown} not in the observation; it has {list(space.spaces)}")
        if not self.keys:
            raise ValueError("keys: give at least one observation key to flatten")
        lows, highs, self.slices, start = [], [], {}, 0
        self._onehot: dict[str, np.ndarray] = {}  # key -> offset of each element's one-hot block
        for k in self.keys:
            box = space.spaces[k]
            if isinstance(box, spaces.MultiDiscrete) and box.nvec.ndim == 1:
                nvec = box.nvec.astype(np.int64)
                self._onehot[k] = np.concatenate([[0], np.cumsum(nvec)[:-1]]) - box.start.astype(np.int64)
                lows.append(np.zeros(int(nvec.sum()), np.float32))
                highs.append(np.ones(int(nvec.sum()), np.float32))
            elif isinstance(box, spaces.Box):
                lows.append(np.asarray(box.low, dtype=np.float32).ravel())
                highs.append(np.asarray(box.high, dtype=np.float32).ravel())
            else:
                raise TypeError(f"observation entry {k!r} is {box}, not a Box or a 1-D MultiDiscrete")
            self.slices[k] = slice(start, start + lows[-1].size)
            start += lows[-1].size
        self.observation_space = spaces.Box(np.concatenate(lows), np.concatenate(highs), dtype=np.float32)

    def observation(self, observation: dict) -> np.ndarray:
        parts = []
        for k in self.keys:
            if k in self._onehot:
                v = np.zeros(self.slices[k].stop - self.slices[k].start, np.float32)
                v[self._onehot[k] + np.asarray(observation[k], dtype=np.int64)] = 1.0
                parts.append(v)
            else:
                parts.append(np.asarray(observation[k], dtype=np.float32).ravel())
        return np.concatenate(parts)


class CheckedReset(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Check ``reset(seed=..., options=...)`` before the wrappers inside see the call.

    Gymnasium's ``TimeLimit.reset`` zeroes its step counter *before* it calls the env, so a
    reset the env rejects (a bad ``options`` entry) would otherwise leave the old episode
    running with a fresh time limit. ``gym.make`` puts this wrapper outside ``TimeLimit``
    for every registered semreloc env (``additional_wrappers`` at registration); wrap your
    own stacks with it outermost if they hold counters that ``reset`` clears first.
    A rejected reset raises ``ValueError`` and changes nothing in any wrapper. Besides the env's
    own checks it refuses a ``kidnap_at_step`` beyond the time limit of a ``TimeLimit`` inside
    it (the kidnap would never happen). A reset that the checks let pass but that fails inside the env
    (a layout with no free place for a random start, say) puts the wrappers' attributes back as they were (the env
    puts back its own), so the running episode keeps its time limit and Gymnasium's checker does not count the
    failed reset as the first. The attributes are put back, not the objects they hold: a wrapper that empties a
    container of its own in place before it calls the env's reset (Gymnasium's ``DelayObservation`` its queue)
    keeps it emptied.
    """

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)

    def reset(self, *, seed=None, options=None):
        check_reset(self.env, seed=seed, options=options)
        saved = []
        inner = self.env
        while isinstance(inner, gym.Wrapper):
            saved.append((inner, dict(inner.__dict__)))
            inner = inner.env
        try:
            return self.env.reset(seed=seed, options=options)
        except BaseException:
            for wrapper, state in saved:
                wrapper.__dict__.clear()
                wrapper.__dict__.update(state)
            raise


class ResetOptions(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Reset with ``options`` merged into those of every ``reset`` call (the call's entries win): for example
    ``ResetOptions(env, {"tracking": True, "kidnap_at_step": 30, "kidnap_pose": "lookalike"})`` makes every
    episode a look-alike kidnapping, also under SB3's vec envs, which reset without options. The env checks the
    merged options at each reset, as any options. ``options``: a mapping (ValueError otherwise)."""

    def __init__(self, env: gym.Env, options: Mapping):
        if not isinstance(options, Mapping):
            raise ValueError(f"options must be a mapping of reset options, got {type(options).__name__}")
        gym.utils.RecordConstructorArgs.__init__(self, options=options)
        gym.Wrapper.__init__(self, env)
        self.options = dict(options)

    def _merged(self, options) -> dict:
        if options is not None and not isinstance(options, Mapping):  # as the env itself says it
            raise ValueError(f"reset options must be a dict or None, got {type(options).__name__} {options!r:.60}")
        return {**self.options, **(options or {})}

    def reset(self, *, seed=None, options=None):
        return self.env.reset(seed=seed, options=self._merged(options))

    def check_reset_through(self, seed, options, inner) -> None:
        """`check_reset`'s hook: the inner envs check the merged options."""
        inner(seed, self._merged(options))


def check_reset(env: gym.Env, seed=None, options=None) -> None:
    """ValueError unless ``env.reset(seed=seed, options=options)`` would be taken; changes nothing.

    The env's own ``check_reset`` and, for a ``kidnap_at_step``, the time limit of a ``TimeLimit`` in
    ``env``'s wrapper chain (a kidnap after it would never happen). A wrapper in the chain that changes what the env
    is reset with (the options, as `ResetOptions`; the layout, as `semreloc_env.layout_sampling.RandomLayout`) takes
    part through its method ``check_reset_through(seed, options, inner)``: it calls ``inner(seed, options)`` with
    what its own reset would pass inward, in the state that reset would leave the env in, and puts that state
    back (so a batched env checks every robot's reset as the robot's wrappers will make it)."""
    _check_reset(env, seed, options, _time_limit(env))


def _check_reset(env: gym.Env, seed, options, limit: int | None) -> None:
    """`check_reset` from ``env`` inward, with the chain's time limit ``limit``."""
    while isinstance(env, gym.Wrapper):
        if hasattr(type(env), "check_reset_through"):
            env.check_reset_through(seed, options, functools.partial(_check_reset, env.env, limit=limit))
            return
        env = env.env
    env.check_reset(seed=seed, options=options)
    k = (options or {}).get("kidnap_at_step")
    if k is not None and limit is not None and k > limit:
        raise KidnapBeyondLimitError(
            f"kidnap_at_step {k} is beyond the episode's time limit of {limit} steps: the kidnap would never happen"
        )


def find_wrapper(env: gym.Env, wrapper_class: type[gym.Wrapper]) -> gym.Wrapper | None:
    """The outermost wrapper of class ``wrapper_class`` in ``env``'s wrapper chain, or None."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, wrapper_class):
            return env
        env = env.env
    return None


def _time_limit(env: gym.Env) -> int | None:
    """The smallest ``max_episode_steps`` of the ``TimeLimit`` wrappers in ``env``'s chain (the one that ends the
    episode first), or None."""
    limits = []
    while isinstance(env, gym.Wrapper):
        if isinstance(env, gym.wrappers.TimeLimit):
            limits.append(env._max_episode_steps)
        env = env.env
    return min(limits, default=None)


class KidnapBeyondLimitError(ValueError):
    """A reset's ``kidnap_at_step`` beyond the episode's time limit (`check_reset`): the kidnap would never happen."""


from .observations import ActiveObservation  # noqa: E402  (the spatial observation for active relocalization)

__all__ = [
    "BELIEF_FEATURES",
    "ActionRepeat",
    "ActiveObservation",
    "BeliefObservation",
    "CheckedReset",
    "ResetOptions",
    "check_reset",
    "FlatObservation",
    "find_wrapper",
]


class ActionRepeat(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Send each action ``repeat`` times (fewer if the episode ends): one decision per ``repeat`` steps.

    The returned observation, ``terminated``, ``truncated`` and ``info`` are those of the last
    inner step; the reward is the sum over the inner steps, and ``info["rewards"]`` the sum of each
    named term. ``info["inner_steps"]`` is how many env steps the call took. Everything else in
    ``info`` (``collided``, ``belief``, ...) is the last inner step's, so per-step counters outside
    (SB3's ``Monitor``, `agents.callbacks`) count decisions, not env steps. A policy trained
    through this wrapper acts on an unwrapped env by holding each action for ``repeat`` steps
    (`agents.learned.LearnedPolicy` does).

    Args:
        env: any env.
        repeat: env steps per action, ``>= 1``.
    """

    def __init__(self, env: gym.Env, repeat: int):
        gym.utils.RecordConstructorArgs.__init__(self, repeat=repeat)
        gym.Wrapper.__init__(self, env)
        if not is_int(repeat) or repeat < 1:
            raise ValueError(f"repeat must be an integer >= 1, got {repeat!r}")
        self.repeat = int(repeat)

    def step(self, action):
        total, terms, n = 0.0, {}, 0
        while n < self.repeat:
            obs, reward, terminated, truncated, info = self.env.step(action)
            n += 1
            total += float(reward)
            for name, value in info.get("rewards", {}).items():
                terms[name] = terms.get(name, 0.0) + float(value)
            if terminated or truncated:
                break
        info = {**info, "rewards": terms, "inner_steps": n}
        return obs, total, terminated, truncated, info
