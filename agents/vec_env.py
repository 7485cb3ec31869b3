"""stable-baselines3 ``VecEnv`` over the batched env (`semreloc_env.envs.batched.SemRelocLoopVectorEnv`).

SB3 resets a finished env inside the same ``step`` (its ``terminal_observation`` goes to the
info, ``TimeLimit.truncated`` marks time-outs), Gymnasium's vector envs reset on the next
step; the adapter drives the batched env's robots with SB3's rule, so a policy trained on it
sees what it would see with ``DummyVecEnv`` over the same envs. Infos are per-robot dicts
(not copied: the env builds a new one every step).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvObs, VecEnvStepReturn

from filters.numbers import is_int
from semreloc_env.envs.batched import SemRelocLoopVectorEnv


def close_after_interrupt(venv) -> None:
    """Close ``venv`` after Ctrl-C: its subprocess workers got the SIGINT too and may be gone, so the pipes'
    errors (``EOFError``, ``BrokenPipeError``, ...) on closing are expected, not news."""
    try:
        venv.close()
    except (EOFError, OSError):
        pass


@contextlib.contextmanager
def closing_venv(venv) -> Iterator:
    """Close ``venv`` when the block ends: quietly after Ctrl-C (`close_after_interrupt`), plainly otherwise
    (an error in the block included)."""
    try:
        yield venv
    except KeyboardInterrupt:
        close_after_interrupt(venv)
        raise
    except BaseException:
        venv.close()
        raise
    venv.close()


def check_seed(seed):
    """``seed`` as an int or None; ValueError for anything else, negatives included (SB3's ``VecEnv.seed`` would add an
    index to it, and a negative seed failed only at every later reset)."""
    if seed is not None and not (is_int(seed) and seed >= 0):
        raise ValueError(f"seed must be None or an int >= 0, got {seed!r:.80}")
    return None if seed is None else int(seed)


def options_per_robot(options, num_envs: int) -> list[dict]:
    """SB3's ``set_options`` argument as one options dict per robot (``{}``: none): None, one dict for every robot, or a
    list of ``num_envs`` dicts or Nones; ValueError for anything else (a non-dict stored by SB3 failed at every later
    reset, an int with a TypeError naming nothing)."""
    if options is None:
        return [{} for _ in range(num_envs)]
    if isinstance(options, dict):
        return [deepcopy(options) for _ in range(num_envs)]
    if not isinstance(options, (list, tuple)) or not all(o is None or isinstance(o, dict) for o in options):
        raise ValueError(f"options must be None, a dict or a list of {num_envs} dicts (or None), got {options!r:.80}")
    if len(options) != num_envs:
        raise ValueError(f"got {len(options)} options dicts for {num_envs} robots (one dict, or one per robot)")
    return [deepcopy(o) if o else {} for o in options]


class SB3VecEnvAdapter(VecEnv):
    """SB3 ``VecEnv`` view of a `SemRelocLoopVectorEnv` (``venv``); seeds via `seed` as in SB3."""

    def __init__(self, venv: SemRelocLoopVectorEnv):
        if not isinstance(venv, SemRelocLoopVectorEnv):
            raise TypeError(f"venv must be a SemRelocLoopVectorEnv, got {type(venv).__name__}")
        self.venv = venv
        self.envs = venv.envs
        self.closed = False  # before SB3's __init__, whose get_attr("render_mode") checks it
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        space = venv.single_observation_space
        self._keys = tuple(space.spaces) if isinstance(space, gym.spaces.Dict) else None  # None: one array

    def seed(self, seed: int | None = None):
        """SB3's seeding (robot ``i`` gets ``seed + i`` at the next reset); ValueError unless ``seed`` is None
        or an int."""
        return super().seed(check_seed(seed))

    def set_options(self, options: list[dict] | dict | None = None) -> None:
        """SB3's ``set_options``, checked now: the shape (`options_per_robot`) and every robot's reset with its seed and
        options (ValueError naming the robot); refused options leave the ones set before."""
        per_robot = options_per_robot(options, self.num_envs)
        self.venv.check_seeds(list(self._seeds), [o or None for o in per_robot])
        self._options = per_robot

    def _stack(self, obs_list: list) -> VecEnvObs:
        if self._keys is None:  # a Box observation (FlattenObservation, FlatObservation): one array
            return np.stack(obs_list)
        return {k: np.stack([o[k] for o in obs_list]) for k in self._keys}

    def check_reset(self) -> None:
        """ValueError naming the robot unless every robot takes the seed and options of the next `reset`."""
        self.venv.check_seeds(list(self._seeds), [o or None for o in self._options])

    def reset(self) -> VecEnvObs:
        self._check_open()
        self.check_reset()  # before any robot resets
        obs = []
        for i, env in enumerate(self.envs):
            with self.venv.naming_who_raised(i, "reset"):
                o, self.reset_infos[i] = env.reset(
                    seed=self._seeds[i], **({"options": self._options[i]} if self._options[i] else {})
                )
            obs.append(o)
        self.venv.all_reset()
        self._actions = None
        self._reset_seeds()
        self._reset_options()
        return self._stack(obs)

    def step_async(self, actions: np.ndarray) -> None:
        """RuntimeError after `close` or after a robot raised in the last step or reset (until `reset`); ValueError
        naming the robot if an action is invalid (all are checked before any robot moves)."""
        self._check_open()
        self.venv.check_in_step()
        self._actions = None  # refused actions leave none to step with
        self._actions = self.venv.check_actions(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Step every robot with the actions `step_async` took. RuntimeError, nothing stepped, after `close`, when
        out of step (a robot raised: until `reset`) or without a `step_async` since the last reset."""
        self._check_open()
        self.venv.check_in_step()
        if getattr(self, "_actions", None) is None:
            raise RuntimeError("step_wait() without step_async(actions) first: nothing to step with")
        obs, infos = [], []
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        for i, env in enumerate(self.envs):
            with self.venv.naming_who_raised(i, "step"):
                o, r, term, trunc, info = env.step(self._actions[i])
            rewards[i], dones[i] = r, term or trunc
            info["TimeLimit.truncated"] = bool(trunc and not term)
            if dones[i]:
                info["terminal_observation"] = o
                with self.venv.naming_who_raised(i, "step", ", resetting it after its episode ended"):
                    o, self.reset_infos[i] = env.reset()
            obs.append(o)
            infos.append(info)
        return self._stack(obs), rewards, dones, infos

    def close(self) -> None:
        self.venv.close()
        self.closed = True

    def _check_open(self) -> None:
        if self.closed:
            raise RuntimeError("this SB3VecEnvAdapter is closed")

    def _targets(self, indices) -> list:
        self._check_open()
        return [self.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        """As `DummyVecEnv`: the attribute from the outermost wrapper that has it, else the env."""
        return [env.get_wrapper_attr(attr_name) for env in self._targets(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        """As `DummyVecEnv`: set on each robot's outermost wrapper."""
        for env in self._targets(indices):
            setattr(env, attr_name, value)

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        """As `DummyVecEnv`: the method of the outermost wrapper that has it, else the env's own."""
        return [env.get_wrapper_attr(method_name)(*args, **kwargs) for env in self._targets(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        from stable_baselines3.common import env_util

        return [env_util.is_wrapped(env, wrapper_class) for env in self._targets(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in self.envs]
