"""``ActiveObservation``: what a policy for active relocalization sees (never the true pose)."""

from __future__ import annotations

import math
from collections import OrderedDict

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from filters.numbers import is_int, is_real

from ..envs.spaces import ODOMETRY_BOUND, require_raw_observation, semantic_parts
from ..layouts import CLASS_NAMES
from .hypotheses import hypotheses_of
from .rasters import MapRasters, allocentric_raster, egocentric_raster

HYPOTHESIS_FEATURES = (
    "present",
    "weight",
    "x_norm",
    "y_norm",
    "cos_theta",
    "sin_theta",
    "dx_top_norm",
    "dy_top_norm",
    "cos_dtheta_top",
    "sin_dtheta_top",
    "pos_std_norm",
    "theta_std_norm",
    "particle_share",
)
"""Columns of ``obs["hypotheses"]`` (see `ActiveObservation`)."""

BELIEF_SUMMARY = (
    "entropy_norm",
    "ess_frac",
    "pos_std_norm",
    "theta_std_norm",
    "converged",
    "hypotheses_norm",
    "ego_mass",
)
"""Entries of ``obs["belief"]`` (see `ActiveObservation`)."""

OBSERVATION_KEYS = (
    "ego",
    "global",
    "hypotheses",
    "belief",
    "lidar",
    "semantic_range",
    "semantic_class",
    "odometry",
    "last_action",
)

_SQRT2 = math.sqrt(2.0)


def check_arguments(
    keys=None, ego_size=32, ego_cell_m=0.25, global_size=32, n_heading_bins=4, max_hypotheses=8
) -> tuple[str, ...]:
    """The observation keys `ActiveObservation` takes from these arguments (``keys`` read once, so any
    iterable will do), or ValueError for arguments it would refuse; needs no env, so a training run
    can check its settings before it starts workers."""
    for name, v in (
        ("ego_size", ego_size),
        ("global_size", global_size),
        ("n_heading_bins", n_heading_bins),
        ("max_hypotheses", max_hypotheses),
    ):
        if not is_int(v) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    for name, v in (("ego_size", ego_size), ("global_size", global_size)):
        if v > 512:  # the images are (channels, size, size) per step
            raise ValueError(f"{name} must be at most 512 cells, got {v!r}")
    if not (is_real(ego_cell_m) and math.isfinite(ego_cell_m) and 0.01 <= ego_cell_m <= 10.0):
        raise ValueError(f"ego_cell_m must be a number in [0.01, 10] m, got {ego_cell_m!r}")
    try:
        chosen = OBSERVATION_KEYS if keys is None else tuple(keys)
    except TypeError:
        chosen = None
    if chosen is None or isinstance(keys, str):
        raise ValueError(f"keys must be a list of names from {list(OBSERVATION_KEYS)}, got {keys!r:.80}")
    unknown = [k for k in chosen if k not in OBSERVATION_KEYS]
    if unknown or not chosen:
        raise ValueError(f"keys {unknown or list(chosen)} invalid; choose from {list(OBSERVATION_KEYS)}")
    return chosen


class ActiveObservation(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replace a ``SemReloc`` observation by spatial belief features for a policy.

    Everything comes from the filter (``env.unwrapped.mcl``'s particles and weights,
    ``env.unwrapped.grid``, ``info["belief"]``), the scans and the action taken: never
    ``info["pose"]``, ``info["pose_error"]`` or the simulator's world. Every bound is
    independent of the particle count and of the layout's size, so one policy runs on any
    layout and filter. The *anchor* is the mean pose of the belief's top hypothesis (the
    heaviest, `hypotheses_of`): where the robot
    most probably is, as far as the filter knows. ``L`` is the side of the square that holds
    the map (its larger extent), the unit of normalised lengths.

    Keys (``B = n_heading_bins``, ``C`` = number of classes, ``K = max_hypotheses``):

    * ``ego``: ``Box(0, 1, (B + 2 + C, ego_size, ego_size))``, the egocentric crop around the
      anchor, heading-aligned (`rasters`): B particle-mass
      channels by heading relative to the anchor, occupied, free, one-hot classes;
      ``ego_cell_m`` metres per cell.
    * ``global``: ``Box(0, 1, (B + 2 + C, global_size, global_size))``, the same channels over
      the whole map (headings absolute).
    * ``hypotheses``: ``Box((K, 13))``, the top K hypotheses by weight, rows of
      `HYPOTHESIS_FEATURES`: present 0/1; weight; mean in map-normalised coordinates
      ``[0, 1]``; cos/sin of its heading; its offset from the top hypothesis, in the top
      hypothesis's frame, / ``L`` (``[-sqrt 2, sqrt 2]``); cos/sin of its heading relative to the
      top one; position std / ``L`` (clipped to 1); heading std / pi; share of the particles.
      Absent rows are 0.
    * ``belief``: ``Box(0, 1, (7,))``, `BELIEF_SUMMARY`: entropy / log N, ESS / N, position
      std / ``L``, heading std / pi, converged, hypothesis count / K (clipped), belief mass
      inside the ego crop.
    * ``lidar``: ``Box(0, 1, (lidar beams,))``, ranges / ``range_max_m``.
    * ``semantic_range``: ``Box(0, 1, (camera beams,))``, pseudo-laser ranges / camera ``range_max_m``.
    * ``semantic_class``: ``MultiDiscrete([1 + C] * camera beams)``, the class label per beam
      (0 none, ``k + 1`` class ``k``).
    * ``odometry``: ``Box(-1, 1, (3,))``, the odometry increment / ``(1 m, 1 m, pi)``.
    * ``last_action``: discrete actions ``Box(0, 1, (n,))`` one-hot, continuous ``Box(-1, 1, (2,))``;
      the action of the last step (zeros after a reset).

    Args:
        env: a ``SemReloc`` env, any version (either raw observation layout; anything with
            ``unwrapped.mcl``, ``unwrapped.grid``, ``unwrapped.lidar``, ``unwrapped.camera`` and ``info["belief"]``).
        keys: which keys to keep (default `OBSERVATION_KEYS`, all of them); the observation holds them in
            alphabetical order whatever the order given (Gymnasium's ``Dict`` space sorts its keys).
        ego_size: side of the ego crop in cells, 1-512 (default 32: with ``ego_cell_m`` 8 m, the
            lidar's reach).
        ego_cell_m: cell size of the ego crop (m), 0.01-10.
        global_size: side of the allocentric image in cells, 1-512.
        n_heading_bins: particle-mass channels per image.
        max_hypotheses: rows of ``hypotheses``.

    Rewards, termination and ``info`` pass through unchanged.
    """

    def __init__(
        self,
        env: gym.Env,
        keys=None,
        ego_size: int = 32,
        ego_cell_m: float = 0.25,
        global_size: int = 32,
        n_heading_bins: int = 4,
        max_hypotheses: int = 8,
    ):
        require_raw_observation(env, "ActiveObservation")
        gym.utils.RecordConstructorArgs.__init__(
            self, keys=keys, ego_size=ego_size, ego_cell_m=ego_cell_m, global_size=global_size,
            n_heading_bins=n_heading_bins, max_hypotheses=max_hypotheses,
        )  # fmt: skip
        gym.Wrapper.__init__(self, env)
        self.keys = check_arguments(keys, ego_size, ego_cell_m, global_size, n_heading_bins, max_hypotheses)
        base = env.unwrapped
        for attr in ("lidar", "camera", "action_space", "mcl", "grid"):
            if not hasattr(base, attr):
                raise TypeError(f"ActiveObservation needs a SemReloc env; {type(base).__name__} has no {attr!r}")

        self.ego_size, self.ego_cell_m, self.global_size = int(ego_size), float(ego_cell_m), int(global_size)
        self.n_heading_bins, self.max_hypotheses = int(n_heading_bins), int(max_hypotheses)
        n_cls = len(CLASS_NAMES)
        n_ch = self.n_heading_bins + 2 + n_cls
        self._n_cam = int(base.camera.params.n_beams)
        self._lidar_max = float(base.lidar.params.range_max_m)
        self._cam_max = float(base.camera.params.range_max_m)
        act = env.action_space
        self._discrete = isinstance(act, spaces.Discrete)
        hyp_low = np.zeros((self.max_hypotheses, len(HYPOTHESIS_FEATURES)), np.float32)
        hyp_high = np.ones_like(hyp_low)
        hyp_low[:, [4, 5, 8, 9]] = -1.0
        hyp_low[:, [6, 7]] = -_SQRT2
        hyp_high[:, [6, 7]] = _SQRT2
        all_spaces = {
            "ego": spaces.Box(0.0, 1.0, (n_ch, self.ego_size, self.ego_size), np.float32),
            "global": spaces.Box(0.0, 1.0, (n_ch, self.global_size, self.global_size), np.float32),
            "hypotheses": spaces.Box(hyp_low, hyp_high, dtype=np.float32),
            "belief": spaces.Box(0.0, 1.0, (len(BELIEF_SUMMARY),), np.float32),
            "lidar": spaces.Box(0.0, 1.0, (int(base.lidar.params.n_beams),), np.float32),
            "semantic_range": spaces.Box(0.0, 1.0, (self._n_cam,), np.float32),
            "semantic_class": spaces.MultiDiscrete(np.full(self._n_cam, 1 + n_cls, dtype=np.int64)),
            "odometry": spaces.Box(-1.0, 1.0, (3,), np.float32),
            "last_action": spaces.Box(0.0, 1.0, (int(act.n),), np.float32)
            if self._discrete
            else spaces.Box(-1.0, 1.0, act.shape, np.float32),
        }
        self.observation_space = spaces.Dict({k: all_spaces[k] for k in self.keys})
        self._rasters: OrderedDict[int, MapRasters] = OrderedDict()
        self._last_action = np.zeros(all_spaces["last_action"].shape, np.float32)

    # ------------------------------------------------------------------ pieces
    def rasters_for(self, grid) -> MapRasters:
        """Pooled map channels of ``grid`` (cached per map object, a few at a time)."""
        hit = self._rasters.get(id(grid))
        if hit is not None and hit.grid is grid:
            self._rasters.move_to_end(id(grid))
            return hit
        r = MapRasters(grid, self.ego_cell_m, self.global_size)
        self._rasters[id(grid)] = r
        if len(self._rasters) > 8:
            self._rasters.popitem(last=False)
        return r

    def hypothesis_features(self, hyps: list[dict], rasters: MapRasters) -> np.ndarray:
        """``(K, 13)`` rows of `HYPOTHESIS_FEATURES` for hypotheses sorted by weight."""
        out = np.zeros((self.max_hypotheses, len(HYPOTHESIS_FEATURES)), np.float32)
        if not hyps:
            return out
        n_total = max(sum(int(h["n_particles"]) for h in hyps), 1)
        top = np.asarray(hyps[0]["mean"], dtype=np.float64)
        ct, st = math.cos(top[2]), math.sin(top[2])
        side = rasters.side_m
        for i, h in enumerate(hyps[: self.max_hypotheses]):
            m = np.asarray(h["mean"], dtype=np.float64)
            cov = np.asarray(h["cov"], dtype=np.float64)
            dx, dy = m[0] - top[0], m[1] - top[1]
            xy = rasters.normalised_xy(m[:2])
            out[i] = [
                1.0,
                h["weight"],
                xy[0],
                xy[1],
                math.cos(m[2]),
                math.sin(m[2]),
                (ct * dx + st * dy) / side,
                (-st * dx + ct * dy) / side,
                math.cos(m[2] - top[2]),
                math.sin(m[2] - top[2]),
                math.sqrt(max(cov[0, 0] + cov[1, 1], 0.0)) / side,
                math.sqrt(max(cov[2, 2], 0.0)) / math.pi,
                int(h["n_particles"]) / n_total,
            ]
        space = self.observation_space.spaces.get("hypotheses")
        lo = space.low if space is not None else -_SQRT2
        hi = space.high if space is not None else _SQRT2
        return np.clip(out, lo, hi).astype(np.float32)

    def observe(self, obs: dict, info: dict) -> dict:
        """The wrapped observation of one ``reset`` / ``step`` (reads the filter, never the truth)."""
        base = self.env.unwrapped
        mcl = base.mcl
        rasters = self.rasters_for(base.grid)
        belief = info["belief"]
        hyps = hypotheses_of(self.env, info)
        poses, weights = np.asarray(mcl.poses), np.asarray(mcl.weights)
        # no hypothesis when no cluster reaches belief.cluster_min_weight: the estimate is then the mean
        anchor = np.asarray(hyps[0]["mean"] if hyps else belief["estimate"], dtype=np.float64)
        out: dict[str, np.ndarray] = {}
        need_ego = "ego" in self.keys or "belief" in self.keys
        ego, ego_mass = (
            egocentric_raster(rasters, poses, weights, anchor, self.ego_size, self.n_heading_bins)
            if need_ego
            else (None, 0.0)
        )
        if "ego" in self.keys:
            out["ego"] = ego
        if "global" in self.keys:
            out["global"] = allocentric_raster(rasters, poses, weights, self.n_heading_bins)
        if "hypotheses" in self.keys:
            out["hypotheses"] = self.hypothesis_features(hyps, rasters)
        if "belief" in self.keys:
            n = max(int(belief["n_particles"]), 1)
            raw = [
                belief["entropy_nats"] / math.log(max(n, 2)),
                belief["ess"] / n,
                belief["pos_std_m"] / rasters.side_m,
                belief["theta_std_rad"] / math.pi,
                1.0 if belief["converged"] else 0.0,
                len(hyps) / self.max_hypotheses,
                ego_mass,
            ]
            out["belief"] = np.clip(np.asarray(raw, np.float32), 0.0, 1.0)
        sem_ranges, sem_labels = semantic_parts(obs)  # either raw layout (SemReloc-v2 typed, v1/v0 flat)
        if "lidar" in self.keys:
            out["lidar"] = np.clip(np.asarray(obs["lidar"], np.float32) / self._lidar_max, 0.0, 1.0)
        if "semantic_range" in self.keys:
            out["semantic_range"] = np.clip(sem_ranges / self._cam_max, 0.0, 1.0).astype(np.float32)
        if "semantic_class" in self.keys:
            out["semantic_class"] = np.clip(sem_labels, 0, len(CLASS_NAMES)).astype(np.int64)
        if "odometry" in self.keys:
            out["odometry"] = np.clip(np.asarray(obs["odometry"], np.float32) / ODOMETRY_BOUND, -1.0, 1.0)
        if "last_action" in self.keys:
            out["last_action"] = self._last_action.copy()
        return out

    def _encode_action(self, action) -> np.ndarray:
        if self._discrete:
            a = np.zeros_like(self._last_action)
            a[int(action)] = 1.0
            return a
        return np.clip(np.asarray(action, dtype=np.float32).reshape(self._last_action.shape), -1.0, 1.0)

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, info = self.env.reset(seed=seed, options=options)
        self._last_action = np.zeros_like(self._last_action)
        return self.observe(obs, info), info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self._last_action = self._encode_action(action)
        return self.observe(obs, info), reward, terminated, truncated, info
