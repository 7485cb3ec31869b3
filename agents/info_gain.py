"""An information-gain planner: move where the filter's own sensor model expects to learn most.

Every ``replan_every`` steps `InfoGainPlanner` scores a few motion primitives (short
fixed action sequences: drive ahead, turn and drive, turn in place, turn around) by the
expected entropy reduction of the belief, predicted with the filter's own models:

1. draw ``n_particles`` particles from the filter's belief (``env.unwrapped.mcl``, systematic
   resampling with the planner's generator) — the belief, never the true pose;
2. move each along the primitive by the nominal (noise-free) kinematics; a particle whose path
   comes within the robot radius of an occupied cell of the filter's map stops there and counts
   as a collision;
3. at ``n_views`` poses along the path, ray-cast the lidar and the semantic camera on the
   filter's map (`filters.simulators.grid_raycast`) from every particle ``j``: the scans
   ``z_j`` the robot would get if ``j`` were the truth;
4. weight every particle ``i`` by the filter's measurement model
   (``mcl.measurement_model``, `filters.localization.likelihood_field.LikelihoodFieldModel`):
   ``log w_ij = s * sum_views log p(z_j | x_i)``, with ``s`` the filter's ``likelihood_scale``
   times the number of filter updates the primitive triggers per view (the motion gate's
   ``update_min_d_m`` / ``update_min_a_rad``);
5. the expected posterior entropy ``E_j[H(hypothesis masses of w_.j)]``, the hypotheses being
   the connected clusters of the drawn particles (see `hypothesis_bins`), so the
   spread within one hypothesis does not count as uncertainty; score = prior entropy - expected posterior entropy
   - ``collision_penalty_nats`` x the share of particles that collide.

It executes the best primitive's first ``replan_every`` actions (all of them if shorter) and
plans again. A forward step the real lidar sees blocked (closer than ``clearance_m`` ahead)
becomes a left turn and forces a replan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from filters.numbers import is_int
from filters.pose import wrap_angle
from filters.robot_data.scans import LaserScan, SemanticScan
from filters.simulators.grid_raycast import cast_rays
from filters.smc.resampling import systematic

from .baselines import FORWARD, TURN_LEFT, TURN_RIGHT
from .policies import Policy, _sector_min


@dataclass(frozen=True)
class Primitive:
    """A named sequence of discrete actions (0 forward, 1 left, 2 right)."""

    name: str
    actions: tuple[int, ...]


DEFAULT_PRIMITIVES = (
    Primitive("forward", (FORWARD,) * 12),
    Primitive("left_forward", (TURN_LEFT,) * 8 + (FORWARD,) * 10),
    Primitive("right_forward", (TURN_RIGHT,) * 8 + (FORWARD,) * 10),
    Primitive("turn_left", (TURN_LEFT,) * 16),
    Primitive("turn_right", (TURN_RIGHT,) * 16),
    Primitive("turn_around", (TURN_LEFT,) * 31 + (FORWARD,) * 10),
)
"""Drive 0.6 m; turn ~46 deg and drive 0.5 m (either side); turn ~92 deg in place (either side);
turn ~180 deg and drive 0.5 m (at the default 0.5 m/s, 1 rad/s, 10 Hz)."""


def entropy(mass: np.ndarray) -> float:
    m = mass[mass > 0]
    return float(-(m * np.log(m)).sum())


def belief_sample(mcl, n: int, rng: np.random.Generator) -> np.ndarray:
    """``(min(n, N), 3)`` poses drawn from the filter ``mcl``'s weighted particles: systematic
    resampling with ``rng``, then ``n`` of the draws evenly spaced (so heavy particles repeat)."""
    idx = systematic(mcl.weights, rng)
    idx = idx[np.linspace(0, idx.size - 1, min(n, idx.size)).astype(np.int64)]
    return np.asarray(mcl.poses)[idx]


def hypothesis_bins(poses: np.ndarray, bin_m: float) -> np.ndarray:
    """Hypothesis label per particle of ``poses`` ``(M, 3)``: 8-connected components of occupied
    ``bin_m`` position bins, each split in two by heading when its particles point more than
    90 deg away from the component's circular mean (a place seen from opposite sides)."""
    ix = np.floor(poses[:, 0] / bin_m).astype(np.int64)
    iy = np.floor(poses[:, 1] / bin_m).astype(np.int64)
    ix -= ix.min()
    iy -= iy.min()
    occ = np.zeros((int(iy.max()) + 1, int(ix.max()) + 1), dtype=bool)
    occ[iy, ix] = True
    labels, _ = ndimage.label(occ, structure=np.ones((3, 3), dtype=bool))
    comp = labels[iy, ix] - 1
    n_comp = int(comp.max()) + 1
    mean = np.arctan2(np.bincount(comp, np.sin(poses[:, 2]), n_comp), np.bincount(comp, np.cos(poses[:, 2]), n_comp))
    flipped = np.abs(wrap_angle(poses[:, 2] - mean[comp])) > math.pi / 2
    return 2 * comp + flipped


class InfoGainPlanner(Policy):
    """Pick the motion primitive with the largest expected entropy reduction (see the module doc).

    Args:
        seed: seeds the particle subsampling (restarted at every `reset`).
        n_particles: particles drawn from the belief per plan.
        replan_every: actions executed between plans.
        n_views: poses along a primitive at which the scans are predicted.
        lidar_beams: lidar beams predicted (evenly spread over the lidar's beams).
        primitives: the candidate motions.
        collision_penalty_nats: cost of a colliding primitive, per share of colliding particles.
        cluster_bin_m: position bin of the hypotheses the entropy is taken over.
        clearance_m: a forward step is replaced by a turn when the lidar sees closer than this ahead.
    """

    def __init__(
        self,
        seed: int = 0,
        n_particles: int = 48,
        replan_every: int = 6,
        n_views: int = 3,
        lidar_beams: int = 24,
        primitives: tuple[Primitive, ...] = DEFAULT_PRIMITIVES,
        collision_penalty_nats: float = 1.0,
        cluster_bin_m: float = 0.5,
        clearance_m: float = 0.35,
    ):
        super().__init__(seed)
        for name, v in (("n_particles", n_particles), ("replan_every", replan_every), ("n_views", n_views)):
            if not is_int(v) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if not primitives:
            raise ValueError("primitives must not be empty")
        self.n_particles, self.replan_every, self.n_views = int(n_particles), int(replan_every), int(n_views)
        self.lidar_beams = int(lidar_beams)
        self.primitives = tuple(primitives)
        self.collision_penalty_nats = float(collision_penalty_nats)
        self.cluster_bin_m = float(cluster_bin_m)
        self.clearance_m = float(clearance_m)
        self._queue: list[int] = []
        self.last_scores: dict[str, float] = {}
        """Score (nats) of every primitive at the last plan, for inspection."""

    def wrap(self, env):
        env = super().wrap(env)
        base = env.unwrapped
        for attr in ("mcl_config", "grid", "lidar", "camera", "robot_params"):
            if not hasattr(base, attr):
                raise TypeError(f"InfoGainPlanner needs a SemReloc env; {type(base).__name__} has no {attr!r}")
        return env

    def reset(self) -> None:
        super().reset()
        self._queue = []

    # ------------------------------------------------------------------ prediction
    def _rollout(self, poses: np.ndarray, prim: Primitive, free_dist: np.ndarray, grid, radius: float):
        """Poses at the ``n_views`` view steps ``(V, M, 3)`` and which particles collided ``(M,)``."""
        n = len(prim.actions)
        views = sorted({max(1, round(n * (k + 1) / self.n_views)) for k in range(self.n_views)})
        p = poses.copy()
        hit = np.zeros(p.shape[0], dtype=bool)
        out = []
        h, w = free_dist.shape
        for t, a in enumerate(prim.actions, start=1):
            if a == FORWARD:
                nxt = p.copy()
                nxt[:, 0] += self.step_m * np.cos(p[:, 2])
                nxt[:, 1] += self.step_m * np.sin(p[:, 2])
                row, col = grid.world_to_cell(nxt[:, :2])
                ok = (row >= 0) & (row < h) & (col >= 0) & (col < w)
                clear = np.zeros(p.shape[0], dtype=bool)
                clear[ok] = free_dist[row[ok], col[ok]] > radius
                hit |= ~clear
                p = np.where((~hit)[:, None], nxt, p)
            elif a in (TURN_LEFT, TURN_RIGHT):
                p[:, 2] = wrap_angle(p[:, 2] + (self.step_rad if a == TURN_LEFT else -self.step_rad))
            if t in views:
                out.append(p.copy())
        return np.stack(out), hit

    def _updates_per_view(self, prim: Primitive) -> float:
        c = self.env.unwrapped.mcl_config
        dist = self.step_m * sum(a == FORWARD for a in prim.actions)
        turn = self.step_rad * sum(a in (TURN_LEFT, TURN_RIGHT) for a in prim.actions)
        n_updates = max(dist / max(c.update_min_d_m, 1e-9), turn / max(c.update_min_a_rad, 1e-9), 1.0)
        return n_updates / self.n_views

    def _scans(self, grid, pose, lidar_angles, cam_angles, lidar_max, cam_max, use_semantic):
        r, _, _ = cast_rays(grid, pose, lidar_angles, lidar_max)
        lidar = LaserScan(r, lidar_angles, lidar_max)
        if not use_semantic:
            return lidar, None
        rs, row, col = cast_rays(grid, pose, cam_angles, cam_max)
        labels = np.zeros(rs.size, np.int64)
        hit = row >= 0
        for k in range(len(grid.class_names) - 1, -1, -1):
            labels[hit] = np.where(grid.class_mask(k)[row[hit], col[hit]], k + 1, labels[hit])
        return lidar, SemanticScan(rs, cam_angles, labels, cam_max)

    def plan(self) -> Primitive:
        """Score every primitive on the current belief (sets `last_scores`); the best one."""
        base = self.env.unwrapped
        mcl, grid = base.mcl, base.grid
        model = mcl.measurement_model
        cfg = base.mcl_config
        sample = belief_sample(mcl, self.n_particles, self.rng)
        m = sample.shape[0]
        bins = hypothesis_bins(sample, self.cluster_bin_m)
        n_bins = int(bins.max()) + 1
        prior = entropy(np.bincount(bins, minlength=n_bins) / m)
        lidar_all = base.lidar.angles
        pick = np.linspace(0, lidar_all.size, min(self.lidar_beams, lidar_all.size), endpoint=False).astype(int)
        lidar_angles, cam_angles = lidar_all[pick], base.camera.angles
        lidar_max, cam_max = base.lidar.params.range_max_m, base.camera.params.range_max_m
        free_dist = model.distance_fields_m[0]
        radius = base.robot_params.radius_m
        self.last_scores = {}
        best, best_score = self.primitives[0], -np.inf
        for prim in self.primitives:
            views, hit = self._rollout(sample, prim, free_dist, grid, radius)
            ll = np.zeros((m, m))  # ll[j, i] = log p(z_j | x_i), summed over the views
            for pv in views:
                for j in range(m):
                    lidar, sem = self._scans(
                        grid, pv[j], lidar_angles, cam_angles, lidar_max, cam_max, cfg.use_semantic
                    )
                    ll[j] += model.log_likelihood(pv, lidar, sem)
            logw = cfg.likelihood_scale * self._updates_per_view(prim) * ll
            logw -= logw.max(axis=1, keepdims=True)
            w = np.exp(logw)
            w /= w.sum(axis=1, keepdims=True)
            post = np.zeros((m, n_bins))
            np.add.at(post, (np.repeat(np.arange(m), m), np.tile(bins, m)), w.ravel())
            expected = float(np.mean([entropy(row) for row in post]))
            score = prior - expected - self.collision_penalty_nats * float(hit.mean())
            self.last_scores[prim.name] = score
            if score > best_score + 1e-9:
                best, best_score = prim, score
        return best

    def act(self, obs: dict):
        self.require_wrapped(obs)
        if not self._queue:
            self._queue = list(self.plan().actions[: self.replan_every])
        a = self._queue.pop(0)
        if a == FORWARD and _sector_min(np.asarray(obs["lidar"]), 0.0, 0.5, self.beam_angles) < self.clearance_m:
            a, self._queue = TURN_LEFT, []
        return self.encode(a)
