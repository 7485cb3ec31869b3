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


FRONT = ((0.0, 0.5),)
"""The sector ``(centre, half-width)`` in rad that the policies check before driving forward."""


def sector_mask(angles: np.ndarray, centre_rad: float, half_rad: float) -> np.ndarray:
    """Bool mask of the beams (robot-frame ``angles``) within ``half_rad`` of ``centre_rad``."""
    return np.abs((np.asarray(angles) - centre_rad + np.pi) % (2 * np.pi) - np.pi) <= half_rad


def lidar_beam_angles(env, who: str, sectors=FRONT) -> np.ndarray | None:
    """The robot-frame angles of ``env``'s lidar beams (None for an env without a ``lidar``), for a policy
    that reads the lidar; ValueError naming ``who`` if one of ``sectors`` (``(centre, half-width)`` in rad)
    holds no beam, so the policy would be blind where it looks (one beam, or a lidar that sees ahead only
    for a policy that backs up)."""
    lidar = getattr(env.unwrapped, "lidar", None)
    angles = getattr(lidar, "angles", None)
    if angles is None:
        return None
    angles = np.asarray(angles, dtype=np.float64)
    for centre, half in sectors:
        if not sector_mask(angles, centre, half).any():
            p = lidar.params
            raise ValueError(
                f"{who} needs a lidar beam within {half} rad of {centre:.3g} rad (0 = straight ahead, pi = behind); "
                f"this env's lidar (fov_rad={p.fov_rad:.4g}, n_beams={p.n_beams}) has none there"
            )
    return angles


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
        if not front.any():
            raise ValueError(f"WallFollowExplorer: no lidar beam within {self.front} rad of straight ahead")
        if ranges[front].min() >= self.clearance:
            self._turning = 0
            return FORWARD
        if self._turning == 0:  # pick a side once and keep it until clear (no dithering)
            left = _mean(ranges[(angles > 0) & (angles < np.pi / 2 + 0.3)])
            right = _mean(ranges[(angles < 0) & (angles > -np.pi / 2 - 0.3)])
            self._turning = TURN_LEFT if left >= right else TURN_RIGHT
        return self._turning


def _mean(r: np.ndarray) -> float:
    return float(r.mean()) if r.size else 0.0  # a side without beams counts as blocked


class RandomWalk:
    """Uniformly random discrete actions from the generator passed in."""

    def __init__(self, rng: np.random.Generator, n_actions: int = 4):
        self.rng = rng
        self.n = n_actions

    def reset(self) -> None:
        pass

    def __call__(self, obs: dict) -> int:
        return int(self.rng.integers(0, self.n))
