"""Hand-written policies: a fixed, documented exploration motion and a random walk.

Both act on the env's observation dict (``lidar`` ranges in the env's beam order,
beams evenly spaced from ``-pi`` when the lidar sees all around).
"""

from __future__ import annotations

import numpy as np

FORWARD, TURN_LEFT, TURN_RIGHT, STOP = 0, 1, 2, 3
AS_BOX = {FORWARD: (1.0, 0.0), TURN_LEFT: (0.0, 1.0), TURN_RIGHT: (0.0, -1.0), STOP: (0.0, 0.0)}
"""``(v, omega)`` of each discrete action on an env with continuous actions: the same motion."""


def all_round_angles(n: int) -> np.ndarray:
    """Robot-frame angles of ``n`` lidar beams spread over 360 deg from -pi (the env's default lidar)."""
    return -np.pi + 2 * np.pi * np.arange(n) / n


MIN_ALL_ROUND_BEAMS = 8
"""Fewest beams of an all-round lidar the hand-written policies read: every sector they look at (1 rad wide
and more) then holds a beam."""


def require_all_round_lidar(env, who: str) -> None:
    """ValueError unless ``env``'s lidar sees all round with at least `MIN_ALL_ROUND_BEAMS` beams, as the
    hand-written policies read it (beam ``k`` at ``-pi + 2 pi k / n``). Envs without a ``lidar`` pass."""
    params = getattr(getattr(env.unwrapped, "lidar", None), "params", None)
    if params is None:
        return
    if params.fov_rad < 2 * np.pi - 1e-9 or params.n_beams < MIN_ALL_ROUND_BEAMS:
        raise ValueError(
            f"{who} reads the lidar as seeing all round (fov 2 pi) with at least {MIN_ALL_ROUND_BEAMS} beams; "
            f"this env's lidar has fov_rad={params.fov_rad:.4g} and n_beams={params.n_beams} "
            "(make the env with the default lidar, or another policy)"
        )


class WallFollowExplorer:
    """Drive forward; when the front sector is blocked, turn toward the freer side.

    The exploration motion of the relocalization experiments: deterministic
    given the observations, so every filter variant sees the same drive.

    Args:
        front_half_angle_rad: half-width of the sector that must be clear to go forward.
        clearance_m: the front sector counts as blocked below this range.
        beam_angles: robot-frame angle of every lidar beam (default: 360 deg, from -pi).
    """

    def __init__(self, front_half_angle_rad: float = 0.5, clearance_m: float = 0.7, beam_angles=None):
        self.front = front_half_angle_rad
        self.clearance = clearance_m
        self.beam_angles = beam_angles
        self._turning = 0

    def reset(self) -> None:
        self._turning = 0

    def __call__(self, obs: dict) -> int:
        ranges = np.asarray(obs["lidar"], dtype=np.float64)
        angles = self.beam_angles
        if angles is None:
            angles = all_round_angles(ranges.size)
        front = np.abs(angles) <= self.front
        if ranges[front].min() >= self.clearance:
            self._turning = 0
            return FORWARD
        if self._turning == 0:  # pick a side once and keep it until clear (no dithering)
            left = ranges[(angles > 0) & (angles < np.pi / 2 + 0.3)].mean()
            right = ranges[(angles < 0) & (angles > -np.pi / 2 - 0.3)].mean()
            self._turning = TURN_LEFT if left >= right else TURN_RIGHT
        return self._turning


class RandomWalk:
    """Uniformly random discrete actions from the generator passed in."""

    def __init__(self, rng: np.random.Generator, n_actions: int = 4):
        self.rng = rng
        self.n = n_actions

    def reset(self) -> None:
        pass

    def __call__(self, obs: dict) -> int:
        return int(self.rng.integers(0, self.n))
