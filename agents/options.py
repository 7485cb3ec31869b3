"""Extra discrete actions for learned policies: one step of a hand-written motion.

`MotionOptions` wraps a ``SemReloc`` env with ``Discrete(4)`` actions (0 forward, 1 left,
2 right, 3 stop) and adds one action per named option, numbered from 4 in the order given:

* ``"explore"`` — the action `agents.baselines.WallFollowExplorer` (drive forward; when the
  front is blocked, turn toward the freer side) picks from the latest lidar scan;
* ``"viewpoint"`` — the action `agents.viewpoint.ViewpointPlanner` (drive to the place where
  the belief's hypotheses look most different) picks. The planner sees every observation, also
  of the steps other actions drove, so its path stays anchored to the robot.

Over an env with continuous actions (``Box(-1, 1, (2,))`` of ``(v, omega)``) the actions are the
same: the four are sent as ``(1, 0)``, ``(0, 1)``, ``(0, -1)`` and ``(0, 0)``, the explorer's
step likewise, and the planner's step is its continuous command (it drives arcs,
`agents.viewpoint.ViewpointPlanner.decide_continuous`). So a policy trained with discrete
actions runs on either env.

A policy over these actions can follow a motion where it is good and leave it where it is not:
the learned part is *when to do what*, the motions are among its actions. `ExplorerOption` is
``MotionOptions(env, ("explore",))``, the five actions of the first trained policy.

The options read only the robot's observations and the filter's belief (never the true pose);
their state is reset with the env, and the planner's subsampling is seeded by the reset seed (a reset without a
seed, as a vector env's autoreset, starts it again from the last seed given, so its draws repeat: deterministic,
and they only choose which particles the planner weighs).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from filters.numbers import is_int_dtype

from .baselines import AS_BOX, WallFollowExplorer, lidar_beam_angles

OPTIONS = ("explore", "viewpoint")
"""The motions that can be added, by name."""


def check_options(options) -> tuple[str, ...]:
    """``options`` as a tuple, checked: names from `OPTIONS`, each at most once (empty is fine).

    Raises:
        ValueError: an unknown or repeated name.
    """
    options = tuple(options)
    if any(o not in OPTIONS for o in options) or len(set(options)) < len(options):
        raise ValueError(f"options must be distinct names from {OPTIONS}, got {options!r}")
    return options


EXPLORE = 4
"""The action of ``"explore"`` in `ExplorerOption`."""


def has_semreloc_actions(space: spaces.Space) -> bool:
    """Whether ``space`` is a ``SemReloc`` action space: ``Discrete(4)`` or ``Box(-1, 1, (2,))``."""
    if isinstance(space, spaces.Discrete):
        return space.n == 4 and space.start == 0
    return (
        isinstance(space, spaces.Box)
        and space.shape == (2,)
        and bool(np.all(space.low == -1.0))
        and bool(np.all(space.high == 1.0))
    )


def _restart(planner, seed, obs: dict) -> None:
    """A planner run beside an env starts its episode: seeded by the reset seed (if given), reset,
    fed the first observation."""
    if seed is not None:
        planner.seed = int(seed)
    planner.reset()
    planner.observe(obs)


class MotionOptions(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """``Discrete(4 + len(options))``: the env's four discrete actions, then one step of each option.

    ``info["option_action"]`` is the env action an option chose (only on option steps): an int,
    or the ``(v, omega)`` array with continuous actions.

    Args:
        env: a ``SemReloc`` env with ``action_type="discrete"`` (``Discrete(4)``) or
            ``"continuous"`` (``Box(-1, 1, (2,))``) and a ``lidar`` observation entry.
        options: names from `OPTIONS`, each at most once (none: the four actions alone, which
            over a ``Box`` env lets a policy of the four discrete actions drive it).

    Raises:
        TypeError: another action space.
        ValueError: unknown or repeated option names.
    """

    def __init__(self, env: gym.Env, options: tuple[str, ...] = ("explore",)):
        gym.utils.RecordConstructorArgs.__init__(self, options=options)
        gym.Wrapper.__init__(self, env)
        if not has_semreloc_actions(env.action_space):
            raise TypeError(
                f"{type(self).__name__} needs the Discrete(4) or Box(-1, 1, (2,)) action space, got {env.action_space}"
            )
        self.continuous = isinstance(env.action_space, spaces.Box)
        options = check_options(options)
        angles = lidar_beam_angles(env, f"{type(self).__name__} {list(options)}") if options else None
        self.options = options
        self.action_space = spaces.Discrete(4 + len(options))
        self.explorer = WallFollowExplorer(beam_angles=angles)
        self.planner = None
        if "viewpoint" in options:
            from .viewpoint import ViewpointPlanner

            self.planner = ViewpointPlanner()
            self.planner.wrap(env)
        self._obs: dict | None = None

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.explorer.reset()
        if self.planner is not None:
            _restart(self.planner, kwargs.get("seed"), obs)
        self._obs = obs
        return obs, info

    def _option_action(self, name: str):
        if name == "explore":
            return self._env_action(int(self.explorer(self._obs)))
        if self.continuous:
            return self.planner.decide_continuous(self._obs)
        return self.planner.decide(self._obs)

    def _env_action(self, a: int):
        """The env's action for discrete action ``a`` (0 forward, 1 left, 2 right, 3 stop)."""
        if not self.continuous:
            return a
        return np.array(AS_BOX[a], dtype=np.float32)

    def step(self, action):
        a = np.asarray(action)
        if a.shape != () or not is_int_dtype(a.dtype) or not self.action_space.contains(int(a)):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        if self._obs is None:
            raise RuntimeError("step() before reset()")
        a = int(action)
        option = a >= 4
        a = self._option_action(self.options[a - 4]) if option else self._env_action(a)
        obs, reward, terminated, truncated, info = self.env.step(a)
        if option:
            info = {**info, "option_action": a}
        if self.planner is not None:
            self.planner.observe(obs)
        self._obs = obs
        return obs, reward, terminated, truncated, info


class ExplorerOption(MotionOptions):
    """``Discrete(5)``: the env's four discrete actions, and 4 = one step of the explorer."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)  # before MotionOptions records its options
        super().__init__(env, ("explore",))


class TeacherLabels(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """``info["teacher_action"]``: the discrete action (0 forward, 1 left, 2 right) the viewpoint
    planner would take from the current state, after `reset` and every `step` (the teacher of
    `agents.imitation`).

    The planner sees every observation, whatever action was taken, so its odometry and path stay
    anchored to the robot (as in `MotionOptions`); it reads only the robot's observations and the
    filter's belief. Its particle subsampling is seeded by the reset seed (by the last one given, at a reset
    without one).

    Args:
        env: a ``SemReloc`` env with ``Discrete(4)`` actions (raw observations: put this wrapper
            inside `ActiveObservation` and `ActionRepeat`).
        planner: keyword arguments of `agents.viewpoint.ViewpointPlanner`.
    """

    def __init__(self, env: gym.Env, planner: dict[str, Any] | None = None):
        gym.utils.RecordConstructorArgs.__init__(self, planner=planner)
        gym.Wrapper.__init__(self, env)
        if env.action_space != gym.spaces.Discrete(4):
            raise TypeError(f"TeacherLabels needs the Discrete(4) action space, got {env.action_space}")
        from .viewpoint import ViewpointPlanner

        self.teacher = ViewpointPlanner(**(planner or {}))
        self.teacher.wrap(env)

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        _restart(self.teacher, kwargs.get("seed"), obs)
        return obs, {**info, "teacher_action": self.teacher.decide(obs)}

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.teacher.observe(obs)
        return obs, reward, terminated, truncated, {**info, "teacher_action": self.teacher.decide(obs)}
