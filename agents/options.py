"""An extra discrete action for learned policies: one step of the reactive explorer.

`ExplorerOption` wraps a ``SemReloc`` env with ``Discrete(4)`` actions (0 forward, 1 left,
2 right, 3 stop) and adds action 4, *explore*: the action that
`agents.baselines.WallFollowExplorer` (drive forward; when the front is blocked, turn toward
the freer side) picks from the latest raw lidar scan. A policy over these five actions can follow
the explorer where that is good and leave it (turn toward a hypothesis-telling object, head for a
door) where it is not: the learned part is *when to do what*, the explorer is one of its motions.

The explorer reads only the robot's own lidar (never the true pose); its state (the side it turns
to while blocked) is reset with the env.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .baselines import WallFollowExplorer

EXPLORE = 4
"""The added action."""


class ExplorerOption(gym.Wrapper):
    """``Discrete(5)``: the env's four discrete actions, and 4 = one step of the explorer.

    ``info["explore_action"]`` is the env action the explorer chose (only on explore steps).

    Args:
        env: a ``SemReloc`` env with ``action_type="discrete"`` (``Discrete(4)``) and a ``lidar``
            observation entry.

    Raises:
        TypeError: another action space.
    """

    def __init__(self, env: gym.Env):
        super().__init__(env)
        if not (isinstance(env.action_space, spaces.Discrete) and env.action_space.n == 4):
            raise TypeError(f"ExplorerOption needs the Discrete(4) action space, got {env.action_space}")
        self.action_space = spaces.Discrete(5)
        self.explorer = WallFollowExplorer()
        self._obs: dict | None = None

    def reset(self, **kwargs):
        obs, info = self.env.reset(**kwargs)
        self.explorer.reset()
        self._obs = obs
        return obs, info

    def step(self, action):
        if isinstance(action, (bool, np.bool_)) or not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        a = int(action)
        if a == EXPLORE:
            if self._obs is None:
                raise RuntimeError("step() before reset()")
            a = int(self.explorer(self._obs))
        obs, reward, terminated, truncated, info = self.env.step(a)
        if int(action) == EXPLORE:
            info = {**info, "explore_action": a}
        self._obs = obs
        return obs, reward, terminated, truncated, info
