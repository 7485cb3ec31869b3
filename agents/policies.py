"""Hand-written active-relocalization policies behind one interface.

Every policy has ``wrap(env) -> env`` (the env it acts on; the baselines return it unchanged),
``reset()`` (call at each episode start: it also restarts the policy's own random stream, so an
episode's actions do not depend on the episodes before it) and ``act(obs) -> action``, for the
env's raw observation dict. They work with ``action_type="discrete"`` and ``"continuous"``
(``wrap`` reads which; a discrete forward / turn is sent as ``(1, 0)`` / ``(0, +-1)``).

* `RandomPolicy` — uniformly random discrete actions.
* `SpinPolicy` — turn left in place forever.
* `SpinThenBackUp` — Nav2's old recovery: a full turn in place, then back up 0.5 m
  (continuous actions; with discrete ones, which cannot reverse, a half turn and 0.5 m forward),
  and again.
* `WallFollowPolicy` — `agents.baselines.WallFollowExplorer`.
* `InfoGainPlanner` — picks short motion primitives by the expected entropy reduction of the
  filter's belief.
* `ViewpointPlanner` — drives up to 8 m to the viewpoint that best tells the belief's
  hypotheses apart (`agents.viewpoint`).

`POLICIES` maps names to constructors ``f(seed) -> policy``.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from filters.numbers import is_int, is_real
from semreloc_env.envs.spaces import require_raw_observation, require_single_env
from semreloc_env.wrappers import ActionRepeat, find_wrapper

from .baselines import (
    AS_BOX,
    FORWARD,
    FRONT,
    TURN_LEFT,
    WallFollowExplorer,
    all_round_angles,
    lidar_beam_angles,
    sector_mask,
)

BACKWARD = -1
"""A pseudo-action of the policies here: reverse at full speed (continuous actions only)."""


class Policy:
    """Base class: action encoding for the env's action type, and the interface."""

    def __init__(self, seed: int = 0):
        if not (is_int(seed) and seed >= 0):
            raise ValueError(f"{type(self).__name__}: seed must be an integer >= 0, got {seed!r:.60}")
        self.seed = int(seed)
        self.rng = np.random.default_rng(self.seed)
        self.env: gym.Env | None = None
        self.continuous = False
        self.beam_angles: np.ndarray | None = None  # the env's lidar beams (robot frame, rad), set by `wrap`

    lidar_sectors: tuple[tuple[float, float], ...] = FRONT
    """``(centre, half-width)`` rad of the lidar sectors the policy reads; `wrap` refuses a lidar with no beam in
    one (`agents.baselines.lidar_beam_angles`) and keeps the beams' angles in ``beam_angles``"""

    def wrap(self, env: gym.Env) -> gym.Env:
        """Check ``env`` and keep it for `act`; returns it unchanged.

        Raises:
            TypeError: a vector env, an env whose observation is wrapped already, or another action space than
                SemReloc's: ``Discrete(>= 4)`` (forward, left, right, stop, ...) or ``Box(-1, 1, (2,))`` of (v, omega).
            ValueError: a lidar with no beam in a sector the policy reads, or an env that repeats actions
                (`semreloc_env.wrappers.ActionRepeat`): these policies decide every env step, and those that follow
                their own motion would miss the repeated steps' odometry.
        """
        name = type(self).__name__
        require_single_env(env, name)
        require_raw_observation(env, name)
        repeating = find_wrapper(env, ActionRepeat)
        if repeating is not None:
            raise ValueError(
                f"{name} decides every env step, and the env is wrapped by ActionRepeat(repeat={repeating.repeat}): "
                "pass the env without ActionRepeat"
            )
        self.beam_angles = lidar_beam_angles(env, name, self.lidar_sectors)
        space = env.action_space
        discrete_ok = isinstance(space, spaces.Discrete) and space.n >= 4 and space.start == 0
        box_ok = (
            isinstance(space, spaces.Box)
            and space.shape == (2,)
            and bool(np.all(space.low == -1.0))
            and bool(np.all(space.high == 1.0))
        )
        if not (discrete_ok or box_ok):
            raise TypeError(
                f"{name} needs a SemReloc action space: Discrete(>= 4) (forward, left, right, stop, ...) or "
                f"Box(-1, 1, (2,)) of (v, omega) (a rescaled one would misread its actions); got {space}"
            )
        self.env = env
        self.continuous = isinstance(space, spaces.Box)
        base = env.unwrapped
        robot = getattr(base, "robot_params", None)
        physics = getattr(base, "physics_params", None)
        self.step_m = (robot.max_linear_mps if robot else 0.5) * (physics.dt_s if physics else 0.1)
        self.step_rad = (robot.max_angular_rps if robot else 1.0) * (physics.dt_s if physics else 0.1)
        return env

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def require_wrapped(self, obs: dict | None = None) -> None:
        """RuntimeError unless `wrap` has been called (``act`` needs the env's action type) and the env reset (the
        planners read its belief); with ``obs``, ValueError unless its lidar has the env's beam count."""
        name = type(self).__name__
        if self.env is None:
            raise RuntimeError(f"{name}: call wrap(env) before act(obs)")
        if getattr(self.env.unwrapped, "world", True) is None:
            raise RuntimeError(f"{name}: reset the env before act(obs)")
        if obs is not None and self.beam_angles is not None:
            n = np.shape(obs["lidar"]) if isinstance(obs, dict) and "lidar" in obs else None
            if n != self.beam_angles.shape:
                raise ValueError(
                    f"{name}: obs['lidar'] has shape {n}, the env's lidar {self.beam_angles.shape} (an observation of "
                    "another env, or of a wrapper?)"
                )

    def encode(self, a: int):
        """The env action for a discrete action (or `BACKWARD`)."""
        self.require_wrapped()
        if not self.continuous:
            if a == BACKWARD:
                raise ValueError("discrete actions cannot reverse")
            return int(a)
        v, w = AS_BOX.get(a, (-1.0, 0.0))  # else BACKWARD
        return np.array([v, w], dtype=np.float32)

    def act(self, obs: dict):  # pragma: no cover - overridden
        raise NotImplementedError


class RandomPolicy(Policy):
    """Uniformly random forward / left / right / stop from its seeded generator."""

    lidar_sectors = ()

    def act(self, obs: dict):
        return self.encode(int(self.rng.integers(0, 4)))


class SpinPolicy(Policy):
    """Turn left in place, every step."""

    lidar_sectors = ()

    def act(self, obs: dict):
        return self.encode(TURN_LEFT)


def _sector_min(ranges: np.ndarray, centre_rad: float, half_rad: float, angles: np.ndarray | None = None) -> float:
    """Smallest lidar range in a sector; inf if no beam lies in it. ``angles``: the beams' robot-frame angles
    (default: spread over 360 deg from -pi, the env's default lidar)."""
    in_sector = ranges[sector_mask(all_round_angles(ranges.size) if angles is None else angles, centre_rad, half_rad)]
    return float(np.min(in_sector)) if in_sector.size else math.inf


class SpinThenBackUp(Policy):
    """A full turn in place, then back up ``backup_m`` (Nav2's old spin + backup recovery), repeated.

    With discrete actions, which cannot reverse, the back-up is a half turn and ``backup_m``
    forward. Driving stops early when the lidar sees an obstacle closer than ``clearance_m`` in
    the direction of travel (so `wrap` wants a lidar beam ahead and one behind).
    """

    lidar_sectors = ((0.0, 0.5), (math.pi, 0.5))

    def __init__(self, seed: int = 0, backup_m: float = 0.5, clearance_m: float = 0.45):
        super().__init__(seed)
        for name, v in (("backup_m", backup_m), ("clearance_m", clearance_m)):
            if not (is_real(v) and 0 < v < 1e3):
                raise ValueError(f"SpinThenBackUp: {name} must be a number in (0, 1000) m, got {v!r:.60}")
        self.backup_m, self.clearance_m = float(backup_m), float(clearance_m)
        self._plan: list[int] = []

    def reset(self) -> None:
        super().reset()
        self._plan = []

    def _cycle(self) -> list[int]:
        spin = [TURN_LEFT] * math.ceil(2 * math.pi / self.step_rad)
        drive = math.ceil(self.backup_m / self.step_m)
        if self.continuous:
            return spin + [BACKWARD] * drive
        return spin + [TURN_LEFT] * math.ceil(math.pi / self.step_rad) + [FORWARD] * drive

    def act(self, obs: dict):
        self.require_wrapped(obs)
        if not self._plan:
            self._plan = self._cycle()
        a = self._plan.pop(0)
        if a in (FORWARD, BACKWARD):
            centre = 0.0 if a == FORWARD else math.pi
            if _sector_min(np.asarray(obs["lidar"]), centre, 0.5, self.beam_angles) < self.clearance_m:
                self._plan = [x for x in self._plan if x not in (FORWARD, BACKWARD)]  # skip the drive
                a = TURN_LEFT
        return self.encode(a)


class WallFollowPolicy(Policy):
    """`agents.baselines.WallFollowExplorer` behind the common interface."""

    def __init__(self, seed: int = 0, **kwargs):
        super().__init__(seed)
        self.explorer = WallFollowExplorer(**kwargs)

    def wrap(self, env: gym.Env) -> gym.Env:
        env = super().wrap(env)
        self.explorer.beam_angles = self.beam_angles
        return env

    def reset(self) -> None:
        super().reset()
        self.explorer.reset()

    def act(self, obs: dict):
        self.require_wrapped(obs)
        return self.encode(self.explorer(obs))


def _info_gain(seed: int = 0):
    from .info_gain import InfoGainPlanner

    return InfoGainPlanner(seed=seed)


def _viewpoint(seed: int = 0):
    from .viewpoint import ViewpointPlanner

    return ViewpointPlanner(seed=seed)


POLICIES = {
    "random": RandomPolicy,
    "spin": SpinPolicy,
    "spin_backup": SpinThenBackUp,
    "wall_follow": WallFollowPolicy,
    "info_gain": _info_gain,
    "viewpoint": _viewpoint,
}
"""Baseline name -> constructor ``f(seed) -> policy``."""
