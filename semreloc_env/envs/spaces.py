"""Action decoding and observation spaces shared by the semreloc envs."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from filters.numbers import is_int_dtype

from ..config import CameraParams, LidarParams, RobotParams
from ..layouts import CLASS_NAMES

ACTION_TYPES = ("discrete", "continuous")
DISCRETE_ACTIONS = ("forward", "turn_left", "turn_right", "stop")
_INT_SCALARS = frozenset((int, *(np.dtype(c).type for c in np.typecodes["AllInteger"])))
"""The exact types of a plain integer action (Python's ``int``, NumPy's integer scalars; not ``bool``)."""
ODOMETRY_BOUND = np.array([1.0, 1.0, np.pi], dtype=np.float32)
"""Odometry increments are clipped to ``+-(1 m, 1 m, pi rad)`` per step in the observation."""


ACTION_BOUND_SLACK = 1e-5
"""How far outside ``[-1, 1]`` a continuous action may lie and still be taken, clipped to the bound: float32
rescaling wrappers miss the bounds by rounding (Gymnasium's ``RescaleAction`` maps its own bounds up to 7.7e-6
beyond ``+-1`` for bounds of magnitude 100). Anything further is refused."""


def make_action_space(action_type: str) -> spaces.Space:
    if not isinstance(action_type, str):
        raise ValueError(f"action_type must be a string, one of {list(ACTION_TYPES)}; got {action_type!r:.60}")
    if action_type == "discrete":
        return spaces.Discrete(len(DISCRETE_ACTIONS))
    if action_type == "continuous":
        return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    raise ValueError(f"unknown action_type {action_type!r}; choose one of {list(ACTION_TYPES)}")


def _discrete_command(index: int, robot: RobotParams) -> tuple[float, float]:
    name = DISCRETE_ACTIONS[index]
    v = robot.max_linear_mps if name == "forward" else 0.0
    w = {"turn_left": 1.0, "turn_right": -1.0}.get(name, 0.0) * robot.max_angular_rps
    return v, w


def decode_action(action, action_type: str, space: spaces.Space, robot: RobotParams) -> tuple[float, float]:
    """``(v m/s, omega rad/s)`` for an action; ValueError for anything outside the space or NaN (continuous
    actions within ``ACTION_BOUND_SLACK`` of the Box are clipped to it)."""
    if action_type == "discrete" and type(action) in _INT_SCALARS and space.start <= action < space.start + space.n:
        return _discrete_command(int(action), robot)  # a plain integer in range: what the checks below accept, sooner
    if np.ma.is_masked(action):  # np.asarray would take the values under the mask
        raise ValueError(f"invalid action {action!r:.80}: masked values")
    try:
        a = np.asarray(action)
    except (TypeError, ValueError, RuntimeError):  # RuntimeError: a torch tensor that requires grad
        a = None
    if action_type == "discrete":
        if a is None or a.shape != () or not is_int_dtype(a.dtype) or not space.contains(int(a)):
            raise ValueError(f"invalid action {action!r}: expected an integer in [0, {space.n}) {DISCRETE_ACTIONS}")
        return _discrete_command(int(a), robot)
    if isinstance(action, (list, tuple)) and any(
        isinstance(v, (bool, np.bool_)) or (isinstance(v, np.ndarray) and v.dtype.kind == "b") for v in action
    ):
        a = None  # [True, 0] (or [np.array(True), 0]) would become the numbers [1, 0]
    if a is None or a.shape != (2,) or a.dtype.kind not in "iuf":  # no strings, bools, complex or objects
        raise ValueError(f"invalid action {action!r:.80}: expected two real numbers (v, omega) in [-1, 1]")
    a = a.astype(np.float64)
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > 1.0 + ACTION_BOUND_SLACK):
        raise ValueError(f"invalid action {action!r:.80}: expected two finite numbers (v, omega) in [-1, 1]")
    a = np.clip(a, -1.0, 1.0)
    return float(a[0]) * robot.max_linear_mps, float(a[1]) * robot.max_angular_rps


OBSERVATION_LAYOUTS = ("typed", "flat")
"""``"typed"`` (``SemReloc-v2`` and later, ``SemSlam-v1`` and later): ``semantic_range`` Box + ``semantic_class`` MultiDiscrete;
``"flat"`` (``SemReloc-v1``/``-v0``, ``SemSlam-v0``): one float32 ``semantic`` Box, ranges then labels."""


def _check_layout(layout: str) -> None:
    if layout not in OBSERVATION_LAYOUTS:
        raise ValueError(f"unknown observation layout {layout!r}; choose one of {list(OBSERVATION_LAYOUTS)}")


def make_observation_space(lidar: LidarParams, camera: CameraParams, layout: str = "typed") -> spaces.Dict:
    """The Dict observation space of the semreloc envs (see the env docstrings).

    ``layout="typed"``: ``lidar`` and ``semantic_range`` float32 Boxes (m), ``semantic_class``
    ``MultiDiscrete([1 + len(CLASS_NAMES)] * camera.n_beams)`` (int64, 0 = no object), ``odometry``.
    ``layout="flat"``: ``lidar``, ``semantic`` (float32, ``2 * camera.n_beams``: ranges, then the labels
    as floats), ``odometry``.
    """
    _check_layout(layout)
    n_sem = int(camera.n_beams)
    entries = {"lidar": spaces.Box(0.0, lidar.range_max_m, shape=(int(lidar.n_beams),), dtype=np.float32)}
    if layout == "typed":
        entries["semantic_range"] = spaces.Box(0.0, camera.range_max_m, shape=(n_sem,), dtype=np.float32)
        entries["semantic_class"] = spaces.MultiDiscrete(np.full(n_sem, 1 + len(CLASS_NAMES), dtype=np.int64))
    else:
        sem_low = np.zeros(2 * n_sem, np.float32)
        sem_high = np.concatenate([np.full(n_sem, camera.range_max_m), np.full(n_sem, len(CLASS_NAMES))])
        entries["semantic"] = spaces.Box(sem_low, sem_high.astype(np.float32), dtype=np.float32)
    entries["odometry"] = spaces.Box(-ODOMETRY_BOUND, ODOMETRY_BOUND, dtype=np.float32)
    return spaces.Dict(entries)


def make_observation(lidar_scan, semantic_scan, odom: np.ndarray, layout: str = "typed") -> dict[str, np.ndarray]:
    """One observation in ``layout`` (see `make_observation_space`): fresh, writable arrays."""
    obs = {"lidar": lidar_scan.ranges.astype(np.float32)}
    if layout == "typed":
        # copies: the scan's own arrays are read-only, and an observation is the caller's to change
        obs["semantic_range"] = np.array(semantic_scan.ranges, dtype=np.float32)
        obs["semantic_class"] = np.array(semantic_scan.labels, dtype=np.int64)
    else:
        obs["semantic"] = np.concatenate([semantic_scan.ranges, semantic_scan.labels]).astype(np.float32)
    obs["odometry"] = np.clip(odom, -ODOMETRY_BOUND, ODOMETRY_BOUND).astype(np.float32)
    return obs


def semantic_parts(obs: dict) -> tuple[np.ndarray, np.ndarray]:
    """``(ranges m float64, class labels int64)`` of the semantic camera from a raw observation of either
    layout (``semantic_range`` + ``semantic_class``, or the flat ``semantic`` vector, whose second half
    holds the labels as floats). KeyError if the observation has neither."""
    if "semantic_class" in obs:
        return np.asarray(obs["semantic_range"], dtype=np.float64), np.asarray(obs["semantic_class"], dtype=np.int64)
    sem = np.asarray(obs["semantic"], dtype=np.float64)
    n = sem.shape[-1] // 2
    return sem[..., :n], np.rint(sem[..., n:]).astype(np.int64)


def require_raw_observation(env, who: str) -> None:
    """ValueError unless ``env``'s observations hold its SemReloc env's own scan and odometry entries
    (each raw entry present with the raw space; wrappers that keep them or add entries, such as
    ``TimeLimit``, ``RandomLayout`` or `semreloc_env.wrappers.BeliefObservation`, are fine).

    For what reads scans in metres from the observation (`ActiveObservation`, the baselines): on an
    env already wrapped by `ActiveObservation` its ``lidar`` entry is the same name scaled to [0, 1],
    and reading that as metres gives wrong results without any error."""
    raw = env.unwrapped.observation_space
    if not isinstance(raw, spaces.Dict):
        return  # not a SemReloc env: the caller's own checks say so
    have = getattr(env.observation_space, "spaces", {})
    differ = [k for k, space in raw.spaces.items() if have.get(k) != space]
    if differ:
        hint = " (is it wrapped by ActiveObservation already?)" if "ego" in have or "global" in have else ""
        missing = [k for k in differ if k not in have]
        what = f"lacks the entries {missing}" if missing else f"changes the entries {differ}"
        raise ValueError(
            f"{who} needs the env's own observations (scans in metres){hint}; this env's observation "
            f"({type(env.observation_space).__name__}, from {type(env).__name__}) {what} of "
            f"{type(env.unwrapped).__name__}'s: wrap the raw env instead"
        )


def require_single_env(env, who: str) -> None:
    """TypeError if ``env`` is a vector env (Gymnasium's ``VectorEnv`` or SB3's ``VecEnv``): a policy
    with the baselines' interface keeps per-episode state (a plan, a held option) for one robot."""
    import gymnasium as gym

    if isinstance(env, gym.vector.VectorEnv) or hasattr(env, "num_envs"):
        raise TypeError(
            f"{who} acts on one env at a time, not on a vector env of {getattr(env, 'num_envs', '?')}: make one "
            "policy per env (gym.make each), or run many with scripts/evaluate_active.py --workers N"
        )
