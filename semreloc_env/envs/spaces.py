"""Action decoding and observation spaces shared by the semreloc envs."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ..config import CameraParams, LidarParams, RobotParams
from ..layouts import CLASS_NAMES

ACTION_TYPES = ("discrete", "continuous")
DISCRETE_ACTIONS = ("forward", "turn_left", "turn_right", "stop")
ODOMETRY_BOUND = np.array([1.0, 1.0, np.pi], dtype=np.float32)
"""Odometry increments are clipped to ``+-(1 m, 1 m, pi rad)`` per step in the observation."""


def make_action_space(action_type: str) -> spaces.Space:
    if not isinstance(action_type, str):
        raise ValueError(f"action_type must be a string, one of {list(ACTION_TYPES)}; got {action_type!r:.60}")
    if action_type == "discrete":
        return spaces.Discrete(len(DISCRETE_ACTIONS))
    if action_type == "continuous":
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    raise ValueError(f"unknown action_type {action_type!r}; choose one of {list(ACTION_TYPES)}")


def decode_action(action, action_type: str, space: spaces.Space, robot: RobotParams) -> tuple[float, float]:
    """``(v m/s, omega rad/s)`` for an action; ValueError for anything outside the space or NaN."""
    if action_type == "discrete":
        a = np.asarray(action)
        if a.shape != () or not np.issubdtype(a.dtype, np.integer) or not space.contains(int(a)):
            raise ValueError(f"invalid action {action!r}: expected an integer in [0, {space.n}) {DISCRETE_ACTIONS}")
        name = DISCRETE_ACTIONS[int(a)]
        v = robot.max_linear_mps if name == "forward" else 0.0
        w = {"turn_left": 1.0, "turn_right": -1.0}.get(name, 0.0) * robot.max_angular_rps
        return v, w
    try:
        a = np.asarray(action)
    except (TypeError, ValueError):
        a = None
    if isinstance(action, (list, tuple)) and any(isinstance(v, (bool, np.bool_)) for v in action):
        a = None  # [True, 0] would become the ints [1, 0]
    if a is None or a.shape != (2,) or a.dtype.kind not in "iuf":  # no strings, bools, complex or objects
        raise ValueError(f"invalid action {action!r:.80}: expected two real numbers (v, omega) in [-1, 1]")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1.0):  # the Box's bounds, exactly
        raise ValueError(f"invalid action {action!r:.80}: expected two finite numbers (v, omega) in [-1, 1]")
    return float(a[0]) * robot.max_linear_mps, float(a[1]) * robot.max_angular_rps


def make_observation_space(lidar: LidarParams, camera: CameraParams) -> spaces.Dict:
    """The Dict of float32 boxes every semreloc env observes (see the env docstrings)."""
    n_sem = int(camera.n_beams)
    sem_low = np.zeros(2 * n_sem, np.float32)
    sem_high = np.concatenate([np.full(n_sem, camera.range_max_m), np.full(n_sem, len(CLASS_NAMES))]).astype(np.float32)
    return spaces.Dict(
        {
            "lidar": spaces.Box(0.0, lidar.range_max_m, shape=(int(lidar.n_beams),), dtype=np.float32),
            "semantic": spaces.Box(sem_low, sem_high, dtype=np.float32),
            "odometry": spaces.Box(-ODOMETRY_BOUND, ODOMETRY_BOUND, dtype=np.float32),
        }
    )


def make_observation(lidar_scan, semantic_scan, odom: np.ndarray) -> dict[str, np.ndarray]:
    return {
        "lidar": lidar_scan.ranges.astype(np.float32),
        "semantic": np.concatenate([semantic_scan.ranges, semantic_scan.labels]).astype(np.float32),
        "odometry": np.clip(odom, -ODOMETRY_BOUND, ODOMETRY_BOUND).astype(np.float32),
    }
