"""A viewpoint planner: drive to the nearest place from which the belief's hypotheses look different.

`agents.info_gain.InfoGainPlanner` looks 0.6 m ahead: in a room that looks exactly like
another, no short motion tells them apart, so it turns on the spot. `ViewpointPlanner` looks
as far as ``horizon_m`` of driving (a shortest path on the filter's map), from the belief
alone (never the true pose):

1. **Hypotheses.** The filter's clusters (``env.unwrapped.belief.hypotheses``, heaviest
   first, at most ``max_hypotheses``); when they hold less than half the mass, or are one
   cluster of a belief that has not converged (spread too wide to be one place), a systematic
   sample of ``n_particles`` particles grouped into ``cluster_bin_m`` clusters
   (`agents.info_gain.hypothesis_bins`). The *reference* is the heaviest of them from which
   the map leaves room to plan (``min_reachable``; else the next of the first three).
2. **Candidate viewpoints.** Places reachable from the reference on a ``plan_cell_m`` grid of
   the map's free space with ``radius + clearance_m`` of clearance (`scipy.sparse.csgraph`
   Dijkstra, 8-connected), within ``horizon_m``, every ``candidate_stride``-th cell, each with
   ``n_headings`` headings.
3. **What each hypothesis would see there.** Driving the reference to a viewpoint ``v`` is the
   motion ``u = ref^-1 * v`` in the robot's own frame; hypothesis ``k`` would then be at
   ``h_k * u``. From every such pose, ``n_rays`` rays all around are cast on the filter's map
   (the lidar's range, and the class of the cell hit within the camera's range).
4. **Score: the expected entropy reduction, with the filter's own sensor model.** For every
   viewpoint, heading and pair ``(k, l)``, the rays of the scan ``k`` would get are scored at
   ``l``'s pose in the filter's likelihood fields (lidar field for every ray that hits,
   the class field for the labelled rays in the camera's field of view; the per-ray mean times
   the number of beams the filter uses; with ``negative_evidence`` and a relocalizer that weighs
   it, as `SemReloc-v5`'s to `-v7`'s do, also ``k``'s unlabelled camera returns, sampled as the filter
   samples them and scored in its negative-evidence table at ``l``'s pose: objects ``l`` would
   see there that ``k``'s scan shows to be absent). Raised to
   ``likelihood_scale * views`` (``views`` filter updates at the viewpoint) and times the prior
   weights, that is the posterior over the hypotheses if ``k`` is the truth; a hypothesis whose
   predicted pose is not free is ruled out by the others. A viewpoint the robot reaches by
   turning on the spot is scored without the lidar when the relocalizer leaves it out of
   rotation-only updates (``lidar_on_rotation``).
   The score is the expected entropy removed, as a share of the prior entropy (in ``[0, 1]``),
   minus ``cost_per_m`` times the path length (plus, at their driving
   equivalent, the turn onto the path and the final turn); the best (viewpoint, heading) pair is
   the goal.
5. **Driving.** The path is stored in the robot's frame at planning time and followed with the
   odometry observation (so it survives the hypotheses being re-ordered): turn toward the farthest path
   point within ``lookahead_m`` in straight line of sight when it is more than ``turn_tol_rad``
   off, else drive;
   at the goal, turn to its heading. A plan is made again at the goal, after ``replan_every``
   steps, and when the lidar sees an obstacle in the robot's way closer than ``clearance_stop_m``
   (then the step turns toward the freer side instead). With continuous actions
   (``action_type="continuous"``) the path is followed with arcs, driving and turning at once
   (`ViewpointPlanner._arc`: on the spot only beyond ``arc_max_rad``, the turn to the goal
   heading begun within ``arc_final_m`` of the goal); discrete actions are unaffected. An
   option of continuous actions, off by default (it did not help on the tuning set): backing up
   along the path when its look-ahead point lies more than ``reverse_rad`` behind
   (``reverse_max_m``; only when the lidar sees all round and shows nothing within
   ``clearance_stop_m`` behind).

When one hypothesis is left (nothing to tell apart), no viewpoint resolves anything within the
horizon, a goal where the robot already stands did not settle the belief twice in a row, or (an option,
off by default) the lidar made it turn away from its path ``max_blocked_turns`` times on the same spot, it
drives as `agents.baselines.WallFollowExplorer` for ``explore_steps`` steps, then plans again.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from scipy import ndimage, sparse
from scipy.sparse import csgraph

from filters.numbers import is_int, is_real
from filters.pose import wrap_angle
from filters.simulators.grid_raycast import cast_many_labelled

from .baselines import FORWARD, TURN_LEFT, TURN_RIGHT, WallFollowExplorer, all_round_angles
from .info_gain import belief_sample, hypothesis_bins
from .policies import Policy, _sector_min

STUCK_M = 0.5
"""Safety turns closer than this (m) to the first of a run count toward ``max_blocked_turns``."""


def _moved(pose: np.ndarray, dx: float, dy: float, dth: float) -> np.ndarray:
    """``pose`` moved by the robot-frame increment ``(dx, dy, dth)`` (metres, radians)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    return np.array([pose[0] + c * dx - s * dy, pose[1] + s * dx + c * dy, wrap_angle(pose[2] + dth)])


@numba.njit(cache=True)
def _cross_ll(
    ranges,
    labels,
    xy,
    phi0,
    headings,
    angles,
    fov_half,
    lidar_max,
    cam_min,
    cam_max,
    flat,
    ox,
    oy,
    inv_res,
    w,
    h,
    out_l,
    out_s,
    cnt_l,
    cnt_s,
):
    """Per-ray mean ``log p`` of the scan hypothesis ``k`` would get at every viewpoint, scored at
    hypothesis ``l``'s pose there: ``out_l[p, i, k, l]`` (lidar rays), ``out_s`` (labelled rays in
    the camera's field of view); ``cnt_l[p, i, k]``, ``cnt_s``: how many rays of ``k``'s scan each
    mean is over.

    ``ranges``/``labels`` ``(K, P, B)``: all-round casts from ``xy`` ``(K, P, 2)`` along absolute
    ray angles ``angles`` ``(B,)``; hypothesis ``k``'s heading at viewpoint heading ``headings[i]``
    is ``phi0[k] + headings[i]``. ``flat`` is the model's ``log p`` tables then floors (field 0 =
    occupancy, ``c`` = class ``c - 1``).
    """
    n_k, n_p, n_b = ranges.shape
    n_h = headings.shape[0]
    n_cells = w * h
    n_t = flat.shape[0] // (n_cells + 1)
    floor0 = n_t * n_cells
    # the ray directions and the camera's field of view do not depend on the viewpoint: once per
    # call, with the very operations of the per-viewpoint loop below (so the same bits)
    cos_a = np.empty((n_h, n_k, n_k, n_b))
    sin_a = np.empty((n_h, n_k, n_k, n_b))
    in_fov = np.empty((n_h, n_k, n_b), np.bool_)
    for i in range(n_h):
        for k in range(n_k):
            phi_k = phi0[k] + headings[i]
            for j in range(n_b):
                beta = angles[j] - phi_k  # robot-frame angle of the ray
                bw = beta - 2.0 * math.pi * math.floor((beta + math.pi) / (2.0 * math.pi))
                in_fov[i, k, j] = abs(bw) <= fov_half
                for m in range(n_k):
                    a = beta + (phi0[m] + headings[i])
                    cos_a[i, k, m, j] = math.cos(a)
                    sin_a[i, k, m, j] = math.sin(a)
    for p in range(n_p):
        for i in range(n_h):
            for k in range(n_k):
                for m in range(n_k):
                    bx = (xy[m, p, 0] - ox) * inv_res
                    by = (xy[m, p, 1] - oy) * inv_res
                    acc_l = 0.0
                    acc_s = 0.0
                    n_l = 0
                    n_s = 0
                    for j in range(n_b):
                        r = ranges[k, p, j]
                        ex = bx + r * cos_a[i, k, m, j] * inv_res
                        ey = by + r * sin_a[i, k, m, j] * inv_res
                        inside = ex >= 0.0 and ex < w and ey >= 0.0 and ey < h
                        cell = int(ey) * w + int(ex) if inside else 0
                        if r < lidar_max:
                            acc_l += flat[cell] if inside else flat[floor0]
                            n_l += 1
                        t = labels[k, p, j]
                        if t > 0 and r >= cam_min and r < cam_max and in_fov[i, k, j]:
                            acc_s += flat[t * n_cells + cell] if inside else flat[floor0 + t]
                            n_s += 1
                    out_l[p, i, k, m] = acc_l / n_l if n_l > 0 else 0.0
                    out_s[p, i, k, m] = acc_s / n_s if n_s > 0 else 0.0
                    cnt_l[p, i, k] = n_l
                    cnt_s[p, i, k] = n_s


@numba.njit(cache=True)
def _cross_neg(
    ranges, labels, xy, phi0, headings, angles, fov_half, cam_min, cam_max, table, margin, step, ox, oy, inv_res, w, h,
    out_n, cnt_n,
):  # fmt: skip
    """The relocalizer's negative evidence (`filters.localization.likelihood_field.NegativeEvidenceConfig`)
    of the scan hypothesis ``k`` would get at every viewpoint, scored at hypothesis ``l``'s pose:
    ``out_n[p, i, k, l]`` is the per-ray mean, over ``k``'s unlabelled camera returns (in the field of
    view, in ``[cam_min, cam_max)``, neither neighbouring ray labelled), of the lowest ``table`` value
    of the ray's points (``margin`` short of the return, then every ``step`` towards the robot, down
    to ``step``) placed along the same ray from ``l``'s pose, at absolute angle
    ``angles[j] - phi0[k] + phi0[l]``; ``cnt_n[p, i, k]`` counts those rays. ``table`` is the model's
    ``negative_table`` (``w * h`` cells, then 0 off the map). Arguments otherwise as `_cross_ll`.

    A ray's points and their values do not depend on the viewpoint heading ``i``, only whether the
    ray lies in the camera's view does: the values are computed once per ray, then summed per heading.
    """
    n_k, n_p, n_b = ranges.shape
    n_h = headings.shape[0]
    low = np.zeros((n_k, n_p, n_b, n_k))
    usable = np.zeros((n_k, n_p, n_b), np.bool_)
    for k in range(n_k):
        for p in range(n_p):
            for j in range(n_b):
                r = ranges[k, p, j]
                if labels[k, p, j] > 0 or r < cam_min or r >= cam_max or r - margin < step:
                    continue
                if labels[k, p, (j + 1) % n_b] > 0 or labels[k, p, (j - 1) % n_b] > 0:
                    continue
                usable[k, p, j] = True
                for m in range(n_k):
                    a = angles[j] - phi0[k] + phi0[m]
                    ca, sa = math.cos(a) * inv_res, math.sin(a) * inv_res
                    bx = (xy[m, p, 0] - ox) * inv_res
                    by = (xy[m, p, 1] - oy) * inv_res
                    v = 0.0
                    d = r - margin
                    while d >= step - 1e-9:
                        ex = bx + d * ca
                        ey = by + d * sa
                        if ex >= 0.0 and ex < w and ey >= 0.0 and ey < h:
                            v = min(v, table[int(ey) * w + int(ex)])
                        d -= step
                    low[k, p, j, m] = v
    for i in range(n_h):
        for k in range(n_k):
            phi_k = phi0[k] + headings[i]
            for p in range(n_p):
                n_n = 0
                for m in range(n_k):
                    out_n[p, i, k, m] = 0.0
                for j in range(n_b):
                    if not usable[k, p, j]:
                        continue
                    beta = angles[j] - phi_k
                    bw = beta - 2.0 * math.pi * math.floor((beta + math.pi) / (2.0 * math.pi))
                    if abs(bw) > fov_half:
                        continue
                    n_n += 1
                    for m in range(n_k):
                        out_n[p, i, k, m] += low[k, p, j, m]
                for m in range(n_k):
                    if n_n > 0:
                        out_n[p, i, k, m] /= n_n
                cnt_n[p, i, k] = n_n


@numba.njit(cache=True)
def _clear_segment(ax, ay, bx, by, ox, oy, cell_m, n, node):
    """`_PlanMap.clear_segment`'s test at ``n >= 2`` points ``t = i / (n - 1)`` (NumPy's
    ``linspace`` arithmetic, so the same cells as ``np.linspace`` would give)."""
    h, w = node.shape
    step = 1.0 / (n - 1)
    for i in range(n):
        t = 1.0 if i == n - 1 else i * step
        col = math.floor((ax + t * (bx - ax) - ox) / cell_m)
        row = math.floor((ay + t * (by - ay) - oy) / cell_m)
        if row < 0 or row >= h or col < 0 or col >= w or node[int(row), int(col)] < 0:
            return False
    return True


class _PlanMap:
    """What the planner derives once per filter map: label raster, clearance and the grid graph."""

    def __init__(self, grid, radius_m: float, clearance_m: float, cell_m: float):
        self.grid = grid
        self.log_table: np.ndarray | None = None
        res = grid.resolution_m
        self.occ = np.ascontiguousarray(grid.occupied_mask())
        free = grid.free_mask()
        self.free = free
        labels = np.zeros(grid.shape, np.int64)
        for k in range(len(grid.class_names) - 1, -1, -1):
            labels[grid.class_mask(k)] = k + 1
        self.labels = labels
        clear = ndimage.distance_transform_edt(free) * res  # metres to the nearest non-free cell
        f = max(1, int(round(cell_m / res)))
        self.cell_m = f * res
        h, w = grid.shape[0] // f, grid.shape[1] // f
        rows = np.arange(h) * f + f // 2
        cols = np.arange(w) * f + f // 2
        ok = clear[np.ix_(rows, cols)] >= radius_m + clearance_m
        self.shape = (h, w)
        self.node = -np.ones((h, w), np.int64)
        self.node[ok] = np.arange(int(ok.sum()))
        rr, cc = np.nonzero(ok)
        self.rc = np.stack([rr, cc], axis=1)
        ox, oy = grid.origin_xy_m
        self.xy = np.stack([ox + (cols[cc] + 0.5) * res, oy + (rows[rr] + 0.5) * res], axis=1)
        src, dst, wt = [], [], []
        for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
            r2, c2 = rr + dr, cc + dc
            inside = (r2 >= 0) & (r2 < h) & (c2 >= 0) & (c2 < w)
            j = np.full(rr.size, -1)
            j[inside] = self.node[r2[inside], c2[inside]]
            m = j >= 0
            src.append(self.node[rr[m], cc[m]])
            dst.append(j[m])
            wt.append(np.full(int(m.sum()), self.cell_m * math.hypot(dr, dc)))
        n = self.xy.shape[0]
        src, dst, wt = np.concatenate(src), np.concatenate(dst), np.concatenate(wt)
        # every edge both ways: csgraph's Dijkstra follows stored edges only (directed)
        self.graph = sparse.csr_matrix((np.r_[wt, wt], (np.r_[src, dst], np.r_[dst, src])), shape=(n, n))
        _, comp = csgraph.connected_components(self.graph, directed=False)
        size = np.bincount(comp) if n else np.zeros(0, np.int64)
        # nodes of pockets too small to plan in (a corner the robot squeezed into) are not starts
        self.start_ok = size[comp] >= min(30, int(size.max()) if n else 0)

    def nearest_node(self, xy: np.ndarray, max_m: float) -> int:
        """The graph node nearest to ``xy`` (metres) within ``max_m``, or -1."""
        if self.xy.shape[0] == 0:
            return -1
        d = np.hypot(self.xy[:, 0] - xy[0], self.xy[:, 1] - xy[1])
        d = np.where(self.start_ok, d, np.inf)
        i = int(np.argmin(d))
        return i if d[i] <= max_m else -1

    def clear_segment(self, a, b) -> bool:
        """Whether the straight segment ``a -> b`` (metres) runs through planning cells only:
        ``n`` points evenly spaced from ``a`` to ``b`` (both included), half a cell apart."""
        n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (self.cell_m / 2)) + 1)
        ox, oy = self.grid.origin_xy_m
        return _clear_segment(
            float(a[0]), float(a[1]), float(b[0]), float(b[1]), float(ox), float(oy), self.cell_m, n, self.node
        )


class ViewpointPlanner(Policy):
    """Drive to the viewpoint that best tells the belief's hypotheses apart (see the module doc).

    Args:
        seed: seeds the particle subsampling (restarted at every `reset`).
        horizon_m: longest path to a viewpoint (metres of driving).
        plan_cell_m: cell of the planning grid (metres).
        clearance_m: free space kept beyond the robot's radius on planned paths (metres).
        candidate_stride: every ``candidate_stride``-th planning cell (both axes) is a viewpoint.
        n_headings: headings per viewpoint.
        n_rays: rays cast all around from every predicted pose.
        max_hypotheses: hypotheses compared (the heaviest).
        n_particles: particles drawn when the clusters hold less than half the mass.
        cluster_bin_m: position bin grouping those particles.
        cost_per_m: score lost per metre of driving (and per turn, at its driving equivalent,
            whatever the action type: charging turns less with continuous actions was tried on
            the tuning set and lost pairs, docs/active.md).
        min_score: viewpoints scoring below this are not goals; with none left, drive as the
            explorer instead.
        views: filter updates counted at a viewpoint (the likelihood is raised to this times the
            filter's ``likelihood_scale``). 1 since a later session (6 before): the filter does not
            keep what several updates at one place would add up to (its scan proposals refill the
            look-alikes while nothing telling is in view), and counting 6 made nearby viewpoints
            promise nearly all the entropy gone, so that in corridors and rings the planner dithered
            (docs/active.md, "Counting one update per viewpoint").
        replan_every: steps (observations the planner took in) after which a plan is made again
            even if its goal was not reached.
        explore_steps: steps driven as the explorer before planning again.
        max_blocked_turns: after this many safety turns (the lidar saw something in the way of a forward
            step) while following plans, within `STUCK_M` of each other, drive as the explorer for
            ``explore_steps`` steps (0, the default: never; each safety turn only makes the planner plan
            again, and a path cutting a corner can keep the robot turning on the spot to the end of an
            episode). 6 ended such a livelock on a held-out pair but did not help on the tuning pairs
            (docs/active.md, at a glance), so it is off.
        stay_m: a goal closer than this counts as staying where the robot is.
        max_stays: after this many such plans in a row (the belief did not settle where the model
            said it would), explore instead.
        min_reachable: a hypothesis is the reference only if at least this many planning cells
            are reachable from it; else the next heaviest of the first three is tried, and if none
            has as many, the one of them with the most.
        lookahead_m: the robot steers to the farthest path point it sees in a straight line within
            this distance.
        turn_tol_rad: heading error above which the robot turns in place.
        clearance_stop_m: a forward step with a lidar return less than this ahead of the robot's
            centre and within its radius (+ 5 cm) sideways turns instead.
        start_turn: also charge the turn from the current heading onto the path.
        arc_max_rad: with continuous actions, heading error toward the look-ahead point above
            which the robot turns on the spot; below it, it drives at ``cos(error)`` of full speed
            while turning (an arc). Discrete actions use ``turn_tol_rad`` instead.
        arc_gain: with continuous actions, the share of the heading error turned per step while
            driving (the turn rate is clipped to the robot's maximum).
        arc_final_m: with continuous actions, within this distance of the goal the robot turns
            toward the goal heading while closing in, and arrives once it faces it (0: off).
        reverse_rad: with continuous actions, heading error toward the look-ahead point above
            which the robot backs up along the path (speed ``-cos`` of its back's error, turning
            its back toward the point) instead of turning on the spot, and keeps backing while its
            back is within ``arc_max_rad`` of it; within ``arc_final_m`` of the goal it may close
            in backward. Only when the env's lidar sees all round (beams at most 0.2 rad apart)
            and no return lies within ``clearance_stop_m`` behind the centre and within the
            radius (+ 5 cm) sideways. 0 (the default): never; else in ``(pi/2, pi]``.
        reverse_max_m: back up only when the rest of the path is at most this long (metres;
            ``inf``: any path).
        negative_evidence: score viewpoints with the relocalizer's negative evidence (objects a
            hypothesis would see that the scan shows to be absent) when its model has it on
            (`NegativeEvidenceConfig.p_detect > 0`, as in `SemReloc-v7` and `-v8`); False: lidar and
            labelled rays only, as before this option.
    """

    def __init__(
        self,
        seed: int = 0,
        horizon_m: float = 8.0,
        plan_cell_m: float = 0.15,
        clearance_m: float = 0.1,
        candidate_stride: int = 2,
        n_headings: int = 8,
        n_rays: int = 48,
        max_hypotheses: int = 8,
        n_particles: int = 24,
        cluster_bin_m: float = 0.5,
        cost_per_m: float = 0.05,
        min_score: float = 0.05,
        views: float = 1.0,
        replan_every: int = 40,
        min_reachable: int = 60,
        explore_steps: int = 10,
        stay_m: float = 0.5,
        max_stays: int = 2,
        lookahead_m: float = 2.0,
        turn_tol_rad: float = 0.3,
        clearance_stop_m: float = 0.3,
        start_turn: bool = True,
        arc_max_rad: float = 1.0,
        arc_gain: float = 1.0,
        arc_final_m: float = 0.3,
        reverse_rad: float = 0.0,
        reverse_max_m: float = math.inf,
        negative_evidence: bool = True,
        max_blocked_turns: int = 0,
    ):
        super().__init__(seed)
        if not isinstance(negative_evidence, (bool, np.bool_)):
            raise ValueError(f"negative_evidence must be a bool, got {negative_evidence!r}")
        self.negative_evidence = bool(negative_evidence)
        ints = {
            "candidate_stride": candidate_stride,
            "n_headings": n_headings,
            "n_rays": n_rays,
            "max_hypotheses": max_hypotheses,
            "n_particles": n_particles,
            "replan_every": replan_every,
            "min_reachable": min_reachable,
            "explore_steps": explore_steps,
            "max_stays": max_stays,
        }
        for name, v in ints.items():
            if not is_int(v) or v < 1:
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        v = max_blocked_turns
        if not is_int(v) or v < 0:
            raise ValueError(f"max_blocked_turns must be an integer >= 0 (0: off), got {v!r}")
        self.max_blocked_turns = int(v)
        positive = {
            "horizon_m": horizon_m,
            "plan_cell_m": plan_cell_m,
            "cluster_bin_m": cluster_bin_m,
            "views": views,
            "lookahead_m": lookahead_m,
            "turn_tol_rad": turn_tol_rad,
            "arc_max_rad": arc_max_rad,
            "arc_gain": arc_gain,
        }
        non_negative = {
            "clearance_m": clearance_m,
            "cost_per_m": cost_per_m,
            "min_score": min_score,
            "stay_m": stay_m,
            "clearance_stop_m": clearance_stop_m,
            "arc_final_m": arc_final_m,
        }
        for name, v in {**positive, **non_negative}.items():
            ok = is_real(v)
            if not (ok and math.isfinite(v) and v >= 0 and (v > 0 or name in non_negative)):
                raise ValueError(f"{name} must be a finite number {'>' if name in positive else '>='} 0, got {v!r}")
        self.horizon_m, self.plan_cell_m, self.clearance_m = float(horizon_m), float(plan_cell_m), float(clearance_m)
        self.candidate_stride, self.n_headings, self.n_rays = int(candidate_stride), int(n_headings), int(n_rays)
        self.max_hypotheses, self.n_particles = int(max_hypotheses), int(n_particles)
        self.cluster_bin_m = float(cluster_bin_m)
        self.cost_per_m, self.min_score, self.views = float(cost_per_m), float(min_score), float(views)
        self.replan_every, self.lookahead_m = int(replan_every), float(lookahead_m)
        self.turn_tol_rad, self.clearance_stop_m = float(turn_tol_rad), float(clearance_stop_m)
        self.min_reachable = int(min_reachable)
        self.start_turn = bool(start_turn)
        self.arc_max_rad, self.arc_gain, self.arc_final_m = float(arc_max_rad), float(arc_gain), float(arc_final_m)
        if not (is_real(reverse_rad) and (reverse_rad == 0 or math.pi / 2 < reverse_rad <= math.pi)):
            raise ValueError(f"reverse_rad must be 0 (off) or in (pi/2, pi], got {reverse_rad!r}")
        if not (is_real(reverse_max_m) and not math.isnan(reverse_max_m) and reverse_max_m > 0):
            raise ValueError(f"reverse_max_m must be a number > 0 (inf: any path), got {reverse_max_m!r}")
        self.reverse_rad, self.reverse_max_m = float(reverse_rad), float(reverse_max_m)
        self.explore_steps, self.stay_m, self.max_stays = int(explore_steps), float(stay_m), int(max_stays)
        self._map: _PlanMap | None = None  # of the filter map planned on last
        self._radius_m = 0.2  # the env's robot, at `wrap`
        self._rear_seen = False  # whether the env's lidar sees behind the robot, at `wrap`
        self.explorer = WallFollowExplorer()
        self.last_plan: dict = {}
        """What the last plan found (``score``, ``goal`` in the reference's map frame, ``path_m``,
        ``n_hypotheses``, ``fallback``), for inspection."""
        self.reset()

    def wrap(self, env):
        env = super().wrap(env)
        base = env.unwrapped
        for attr in ("belief", "mcl", "grid", "lidar", "camera", "robot_params"):
            if not hasattr(base, attr):
                raise TypeError(f"ViewpointPlanner needs a SemReloc env; {type(base).__name__} has no {attr!r}")
        self.explorer = WallFollowExplorer(beam_angles=np.asarray(base.lidar.angles))
        self._map = None  # another env may share the grid but not the robot's radius or the filter's model
        self._radius_m = float(base.robot_params.radius_m)
        # backing up needs the lidar to see behind: beams all around, none more than 0.2 rad apart
        b = np.sort(np.mod(np.asarray(base.lidar.angles, dtype=np.float64), 2 * math.pi))
        self._rear_seen = b.size > 1 and float(np.max(np.diff(np.r_[b, b[0] + 2 * math.pi]))) <= 0.2
        return env

    def reset(self) -> None:
        super().reset()
        self.explorer.reset()
        self._path = np.zeros((0, 2))  # remaining path, robot frame at planning time (metres)
        self._goal_heading = 0.0
        self._pose = np.zeros(3)  # the robot's pose in that frame, from the odometry
        self._odo = np.zeros(3)  # the robot's pose in the frame of the episode's start, from the odometry
        self._blocked_from: np.ndarray | None = None  # where (``_odo``) the current run of safety turns began
        self._blocked_turns = 0
        self._escaping = False  # exploring because of `max_blocked_turns`
        self._since_plan = 0
        self._stays = 0
        self._progress_window = max(2, int(1.5 / self.plan_cell_m))
        self._exploring = True
        self._first = True
        self._seen = False
        self._reversing = False
        self._ranges = np.zeros(0)

    # ------------------------------------------------------------------ planning
    def _plan_map(self) -> _PlanMap:
        base = self.env.unwrapped
        if self._map is None or self._map.grid is not base.grid:
            self._map = _PlanMap(base.grid, base.robot_params.radius_m, self.clearance_m, self.plan_cell_m)
        return self._map

    def hypotheses(self) -> tuple[np.ndarray, np.ndarray]:
        """Poses ``(K, 3)`` and weights ``(K,)`` (summing to 1) of the hypotheses compared, heaviest first."""
        base = self.env.unwrapped
        belief = base.belief
        hyps = belief.hypotheses[: self.max_hypotheses]
        if sum(h.weight for h in hyps) >= 0.5 and (len(hyps) > 1 or belief.converged):
            poses = np.array([h.mean for h in hyps], dtype=np.float64)
            w = np.array([h.weight for h in hyps], dtype=np.float64)
        else:
            sample = belief_sample(base.mcl, self.n_particles, self.rng)
            bins = hypothesis_bins(sample, self.cluster_bin_m)
            first = np.unique(bins, return_index=True)[1]
            counts = np.bincount(bins)[bins[first]]
            order = np.argsort(-counts, kind="stable")[: self.max_hypotheses]
            poses, w = sample[first[order]], counts[order].astype(np.float64)
        return poses, w / w.sum()

    def plan(self) -> bool:
        """Plan from the current belief; False when the explorer should drive instead."""
        pm = self._plan_map()
        poses, w = self.hypotheses()
        self.last_plan = {"n_hypotheses": int(poses.shape[0]), "fallback": True, "score": 0.0}
        if poses.shape[0] < 2:
            return False
        # the reference: the heaviest hypothesis from which the map offers room to plan (a
        # hypothesis in a badly mapped corner would give a handful of candidates)
        chosen = None
        for r in range(min(3, poses.shape[0])):
            s = pm.nearest_node(poses[r, :2], 1.0)
            if s < 0:
                continue
            dist, pred = csgraph.dijkstra(pm.graph, indices=s, limit=self.horizon_m, return_predecessors=True)
            reach = np.isfinite(dist)
            if chosen is None or reach.sum() > chosen[3].sum():
                chosen = (r, s, dist, reach, pred)
            if reach.sum() >= self.min_reachable:
                break
        if chosen is None:
            return False
        r, s, dist, reach, pred = chosen
        order = np.r_[r, np.delete(np.arange(poses.shape[0]), r)]
        poses, w = poses[order], w[order]
        ref = poses[0]
        rc = pm.rc
        lattice = (rc[:, 0] % self.candidate_stride == 0) & (rc[:, 1] % self.candidate_stride == 0)
        cand = np.nonzero(reach & lattice)[0]
        cand = np.union1d(cand, [s])
        stay = dist[cand] < self.env.unwrapped.mcl_config.update_min_d_m  # turning on the spot only
        gain, heads = self._gains(pm, poses, w, cand, stay=stay)  # (P, H), (H,)
        turn_m = self._turn_cost_m(pm, pred, dist, s, cand, heads[None, :], ref[2])
        util = np.where(gain >= self.min_score, gain - self.cost_per_m * (dist[cand, None] + turn_m), -np.inf)
        best, bh = np.unravel_index(int(np.argmax(util)), util.shape)
        self.last_plan.update(score=float(gain[best, bh]), n_candidates=int(cand.size))
        if not np.isfinite(util[best, bh]):
            return False
        goal_h = float(heads[bh])
        goal = int(cand[best])
        path = [goal]
        while path[-1] != s:
            path.append(int(pred[path[-1]]))
        pts = pm.xy[np.array(path[::-1])]
        c, sn = math.cos(ref[2]), math.sin(ref[2])
        d = pts - ref[:2]
        self._path = np.stack([c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1]], axis=1)[1:]
        self._goal_heading = float(wrap_angle(goal_h - ref[2]))
        self._pose = np.zeros(3)
        self._ref = ref.copy()
        self.last_plan.update(
            fallback=False,
            goal=[float(pm.xy[goal, 0]), float(pm.xy[goal, 1]), goal_h],
            path_m=float(dist[goal]),
        )
        return True

    def _turn_cost_m(self, pm, pred, dist, s, cand, goal_h, heading) -> np.ndarray:
        """Driving-equivalent metres of the turns a goal asks for: the final turn to the goal
        heading (from the last path segment's direction, or from the current ``heading`` at the
        start node) and, if ``start_turn``, the first turn from ``heading`` toward the path point
        about a metre out."""
        prev = pred[cand]
        prev = np.where(prev < 0, s, prev)
        d = pm.xy[cand] - pm.xy[prev]
        arrive = np.where(cand == s, heading, np.arctan2(d[:, 1], d[:, 0]))
        goal_h = np.asarray(goal_h)
        extra = (1,) * (goal_h.ndim - 1)  # goal headings (P,), or (P, H) / (1, H) per heading
        turn = np.abs(wrap_angle(goal_h - arrive.reshape(arrive.shape + extra)))
        if self.start_turn:
            out = cand.copy()  # walk each path back to its point about 1 m from the start
            while True:
                up = pred[out]
                move = (up >= 0) & (dist[out] > 1.0)
                if not move.any():
                    break
                out = np.where(move, up, out)
            d0 = pm.xy[out] - pm.xy[s]
            leave = np.where(out == s, heading, np.arctan2(d0[:, 1], d0[:, 0]))
            turn = turn + np.abs(wrap_angle(leave - heading)).reshape(leave.shape + extra)
        return turn / max(self.step_rad, 1e-9) * self.step_m

    def _gains(self, pm: _PlanMap, poses: np.ndarray, w: np.ndarray, cand: np.ndarray, stay=None):
        """Expected share of the hypothesis entropy removed at every candidate and heading ``(P, H)``,
        and the headings (absolute, the reference's map frame) ``(H,)``. Where ``stay`` ``(P,)`` is
        set the robot would only turn on the spot: the lidar counts only if the filter uses it in
        updates triggered by rotation alone (``lidar_on_rotation``)."""
        base = self.env.unwrapped
        grid, model, cfg = base.grid, base.mcl.measurement_model, base.mcl_config
        ref = poses[0]
        k_n, p_n, b = poses.shape[0], cand.size, self.n_rays
        # motion u = ref^-1 * v in the robot frame; hypothesis k ends at h_k * u (position part)
        c0, s0 = math.cos(ref[2]), math.sin(ref[2])
        d = pm.xy[cand] - ref[:2]
        u = np.stack([c0 * d[:, 0] + s0 * d[:, 1], -s0 * d[:, 0] + c0 * d[:, 1]], axis=1)
        ck, sk = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        xy = np.empty((k_n, p_n, 2))
        xy[:, :, 0] = poses[:, None, 0] + ck[:, None] * u[None, :, 0] - sk[:, None] * u[None, :, 1]
        xy[:, :, 1] = poses[:, None, 1] + sk[:, None] * u[None, :, 0] + ck[:, None] * u[None, :, 1]
        invalid = ~grid.is_free(xy)  # (K, P): if k were the truth, the robot could not be there
        angles = 2 * math.pi * np.arange(b) / b
        lidar, cam = base.lidar.params, base.camera.params
        ranges = np.empty((k_n * p_n, b))
        labels = np.empty((k_n * p_n, b), np.int64)
        ox, oy = (float(v) for v in grid.origin_xy_m)
        flat_xy = np.ascontiguousarray(xy.reshape(-1, 2))
        res = grid.resolution_m
        cast_many_labelled(
            pm.occ, pm.labels, ox, oy, res, flat_xy, angles, lidar.range_max_m, cam.range_max_m, ranges, labels
        )
        headings = 2 * math.pi * np.arange(self.n_headings) / self.n_headings  # relative to the reference
        if pm.log_table is None:  # the model's log p tables then floors, as the kernel reads them
            tables, floors = model.log_tables(lidar.range_max_m, cam.range_max_m)
            pm.log_table = np.concatenate([tables.ravel(), floors])
        table = pm.log_table
        h_cells, w_cells = grid.shape
        out_l = np.empty((p_n, headings.size, k_n, k_n))
        out_s = np.empty_like(out_l)
        cnt_l = np.zeros((p_n, headings.size, k_n))
        cnt_s = np.zeros_like(cnt_l)
        _cross_ll(
            ranges.reshape(k_n, p_n, b), labels.reshape(k_n, p_n, b), xy, poses[:, 2].copy(), headings,
            angles, cam.fov_rad / 2, lidar.range_max_m, cam.range_min_m, cam.range_max_m, table,
            float(ox), float(oy), 1.0 / grid.resolution_m, w_cells, h_cells, out_l, out_s, cnt_l, cnt_s,
        )  # fmt: skip
        # beams the filter would use: its sensors' beams in the same share as the rays that return
        # (lidar) or see a class (camera), after its stride and cap
        n_fov = max(int(np.sum(np.abs(wrap_angle(angles)) <= cam.fov_rad / 2)), 1)
        lf, sf = cfg.lidar_field, cfg.semantic_field
        n_lidar = np.minimum(cnt_l / b * lidar.n_beams / lf.beam_stride, lf.max_beams or np.inf)
        n_cam = np.minimum(cnt_s / n_fov * cam.n_beams / sf.beam_stride, sf.max_beams or np.inf)
        if stay is not None and not cfg.lidar_on_rotation:
            n_lidar = np.where(np.asarray(stay)[:, None, None], 0.0, n_lidar)
        ll = n_lidar[..., None] * out_l + (n_cam[..., None] * out_s if cfg.use_semantic else 0.0)
        neg = model.negative_config
        if self.negative_evidence and cfg.use_semantic and neg.enabled:
            out_n = np.empty_like(out_l)
            cnt_n = np.zeros_like(cnt_l)
            _cross_neg(
                ranges.reshape(k_n, p_n, b), labels.reshape(k_n, p_n, b), xy, poses[:, 2].copy(), headings,
                angles, cam.fov_rad / 2, cam.range_min_m, cam.range_max_m, model.negative_table(), neg.margin_m,
                neg.step_m, float(ox), float(oy), 1.0 / grid.resolution_m, w_cells, h_cells, out_n, cnt_n,
            )  # fmt: skip
            ll = ll + np.minimum(cnt_n / n_fov * cam.n_beams, neg.max_beams)[..., None] * out_n
        # log posterior of hypothesis l when k is the truth, after `views` updates at the viewpoint
        logit = cfg.likelihood_scale * self.views * (ll - np.diagonal(ll, axis1=2, axis2=3)[..., :, None])
        bad = invalid.T[:, None, :, None] | invalid.T[:, None, None, :]
        logit = np.where(bad & ~np.eye(k_n, dtype=bool), -np.inf, logit) + np.log(w)
        logit -= logit.max(axis=3, keepdims=True)
        post = np.exp(logit)
        post /= post.sum(axis=3, keepdims=True)
        with np.errstate(divide="ignore", invalid="ignore"):
            ent = -np.where(post > 0, post * np.log(post), 0.0).sum(axis=3)  # (P, H, K)
        prior = float(-(w * np.log(w)).sum())
        # if k is the truth and its image of the viewpoint is not free, the robot does not get there:
        # that row tells nothing (the prior), rather than the certainty its ruled-out rivals suggest
        ent = np.where(invalid.T[:, None, :], prior, ent)
        gain = (prior - ent @ w) / max(prior, 1e-12)  # (P, H)
        return gain, wrap_angle(ref[2] + headings)

    # ------------------------------------------------------------------ acting
    def _integrate(self, odom: np.ndarray) -> None:
        dx, dy, dth = (float(v) for v in odom[:3])
        self._pose = _moved(self._pose, dx, dy, dth)
        self._odo = _moved(self._odo, dx, dy, dth)

    def _follow(self) -> int | None:
        """The next discrete action along the stored path; None when the goal is reached.

        Steers to the farthest path point within ``lookahead_m`` that the robot sees in a straight
        line through planning cells (so it cuts the grid path's zigzags)."""
        step = self._track()
        if step is None:
            return None
        err, target = step
        if target is None or abs(err) > self.turn_tol_rad:  # (at the goal, `_track` leaves only turns)
            return TURN_LEFT if err > 0 else TURN_RIGHT
        return FORWARD

    def _track(self) -> tuple[float, np.ndarray | None] | None:
        """Where the path asks the robot to head: ``(heading error, target point)`` while on the
        path (the farthest point within ``lookahead_m`` in straight line of sight, robot frame at
        planning time), ``(error to the goal heading, None)`` at its end, None when the goal is
        reached with its heading (within a turn step)."""
        x, y, th = self._pose
        c, s = math.cos(self._ref[2]), math.sin(self._ref[2])
        here = self._ref[:2] + (c * x - s * y, s * x + c * y)

        def seen(pt) -> bool:  # in straight line of sight through planning cells
            return self._map.clear_segment(here, self._ref[:2] + (c * pt[0] - s * pt[1], s * pt[0] + c * pt[1]))

        if self._path.shape[0] > 1:  # progress: drop the points before the nearest one ahead in sight
            ahead = self._path[: self._progress_window]
            d = np.hypot(ahead[:, 0] - x, ahead[:, 1] - y)
            near = next((int(i) for i in np.argsort(d, kind="stable") if seen(ahead[i])), 0)
            passed = near + 1 < self._path.shape[0] and d[near] < 0.3
            self._path = self._path[near + passed :]
        if self._path.shape[0] == 1 and math.hypot(*(self._path[0] - (x, y))) < 0.15:
            self._path = self._path[:0]
        if self._path.shape[0]:
            target = self._path[0]
            for pt in self._path[1:]:
                if math.hypot(*(pt - (x, y))) > self.lookahead_m or not seen(pt):
                    break
                target = pt
            return float(wrap_angle(math.atan2(target[1] - y, target[0] - x) - th)), target
        err = float(wrap_angle(self._goal_heading - th))
        if abs(err) > self.step_rad:
            return err, None
        return None

    def _arc(self) -> np.ndarray | None:
        """The next continuous command ``(v, omega)`` in ``[-1, 1]`` along the stored path (arcs);
        None when the goal is reached.

        On the path: turn on the spot (as fast as the error asks, at most a turn step) when the
        look-ahead point is more than ``arc_max_rad`` off; else drive at ``cos(error)`` of full
        speed while turning toward it, ``arc_gain`` of the error per step. Within ``arc_final_m``
        of the goal (the look-ahead point being the goal), turn toward the goal heading instead
        while still closing in (speed ``cos`` of the error toward the goal point, none if it lies
        behind unless backing up is allowed); facing the goal heading there counts as arrived.
        With ``reverse_rad`` set, a look-ahead point more than ``reverse_rad`` off (behind) is
        backed up to, the same rule applied to the robot's back, while the lidar shows the way
        back clear (`_blocked` ``behind=True``); else the turn on the spot."""
        step = self._track()
        if step is None:
            self._reversing = False
            return None
        err, target = step
        turn = self.step_rad
        back_ok = (  # no scan taken in yet (`_decide` sets it): no backing up
            self.reverse_rad > 0 and self._rear_seen and self._ranges.size > 0
            and not self._blocked(self._ranges, behind=True)
        )  # fmt: skip
        if target is not None and self.arc_final_m > 0 and np.array_equal(target, self._path[-1]):
            x, y, th = self._pose
            if math.hypot(target[0] - x, target[1] - y) < self.arc_final_m:
                err_h = float(wrap_angle(self._goal_heading - th))
                if abs(err_h) <= self.step_rad:  # facing the goal heading, close enough: arrived
                    self._path = self._path[:0]
                    return self._arc()
                v = math.cos(err) if back_ok else max(0.0, math.cos(err))
                return np.array([v, np.clip(err_h / turn, -1.0, 1.0)], dtype=np.float32)
        if target is not None and back_ok:
            rear = float(wrap_angle(err - math.pi))  # how far the robot's back is off the target
            keep = self._reversing and abs(rear) <= self.arc_max_rad
            if (keep or abs(err) > self.reverse_rad) and self._path_left_m() <= self.reverse_max_m:
                self._reversing = True
                omega = float(np.clip(self.arc_gain * rear / turn, -1.0, 1.0))
                return np.array([-math.cos(rear), omega], dtype=np.float32)
        self._reversing = False
        omega = float(np.clip(err / turn, -1.0, 1.0))
        if target is None or abs(err) > self.arc_max_rad:
            return np.array([0.0, omega], dtype=np.float32)
        omega = float(np.clip(self.arc_gain * err / turn, -1.0, 1.0))
        return np.array([math.cos(err), omega], dtype=np.float32)

    def _path_left_m(self) -> float:
        """Metres from the robot along the rest of the stored path."""
        pts = np.vstack([self._pose[None, :2], self._path])
        return float(np.hypot(*np.diff(pts, axis=0).T).sum())

    def _replan(self) -> None:
        ok = self.plan()
        # a goal where the robot already is that did not settle the belief: the model promised
        # more than the filter delivers there, so move on instead of turning on the spot again
        self._stays = self._stays + 1 if ok and self.last_plan["path_m"] < self.stay_m else 0
        if self._stays > self.max_stays:
            ok, self._stays = False, 0
            self.last_plan["fallback"] = True
        self._exploring = not ok
        self._escaping = False
        self._since_plan = 0

    def observe(self, obs: dict) -> None:
        """Take in an observation of the env (its odometry) without acting. `act` calls it; call it
        yourself on the observations of steps something else drove (`agents.options`), so the
        stored path stays anchored to the robot."""
        if self._seen:
            self._integrate(np.asarray(obs["odometry"], dtype=np.float64))
            self._since_plan += 1
        self._seen = True

    def decide(self, obs: dict) -> int:
        """The discrete action (0 forward, 1 left, 2 right) for the latest observed ``obs``."""
        return int(self._decide(obs, self._follow))

    def decide_continuous(self, obs: dict) -> np.ndarray:
        """The continuous action ``(v, omega)`` (float32, in ``[-1, 1]``) for the latest observed
        ``obs``: the path followed with arcs (`_arc`); the explorer's steps and the safety turn as
        their discrete actions (forward ``(1, 0)``, turns ``(0, +-1)``)."""
        a = self._decide(obs, self._arc)
        return a if isinstance(a, np.ndarray) else self.encode(a)

    def _decide(self, obs: dict, follow):
        """The next action: ``follow()``'s (a discrete action, or a continuous command) while a plan
        is followed, else the explorer's; a forward motion the lidar says would touch something
        becomes a discrete turn toward the freer side."""
        if self._first or self._since_plan >= (self.explore_steps if self._exploring else self.replan_every):
            self._replan()
        self._first = False
        self._ranges = np.asarray(obs["lidar"], dtype=np.float64)
        a = None
        if not self._exploring:
            a = follow()
            if a is None:  # goal reached with its heading
                self._replan()
                a = None if self._exploring else follow()
        if a is None:
            a = self.explorer(obs)
        ranges = self._ranges
        forward = a[0] > 0 if isinstance(a, np.ndarray) else a == FORWARD
        if forward and self._blocked(ranges):
            b = self.beam_angles
            left, right = _sector_min(ranges, math.pi / 2, 0.8, b), _sector_min(ranges, -math.pi / 2, 0.8, b)
            a = TURN_LEFT if left >= right else TURN_RIGHT
            if not self._escaping:  # plan again next step (an exploration the rule began runs its course)
                self._since_plan = self.replan_every
            if not self._exploring:
                self._count_blocked_turn()
        return a

    def _count_blocked_turn(self) -> None:
        """With ``max_blocked_turns``: that many safety turns while following plans, within `STUCK_M` of
        where the first of them was made, mean the plans keep leading into something the lidar sees in the
        way (a path cutting a corner the map rounds off, say), and each new plan turns the robot back toward
        it: drive as the explorer for ``explore_steps`` steps instead (its own safety turns do not cut that
        short), then plan again from wherever that led."""
        if not self.max_blocked_turns:
            return
        start = self._blocked_from
        if start is None or math.hypot(self._odo[0] - start[0], self._odo[1] - start[1]) > STUCK_M:
            self._blocked_from, self._blocked_turns = self._odo.copy(), 0
        self._blocked_turns += 1
        if self._blocked_turns >= self.max_blocked_turns:
            self._exploring, self._escaping, self._since_plan = True, True, 0
            self._blocked_from, self._blocked_turns = None, 0

    def _blocked(self, ranges: np.ndarray, behind: bool = False) -> bool:
        """Whether a lidar return ahead lies within ``clearance_stop_m`` forward of the robot's
        centre and within its radius (+ 5 cm) sideways: the disc would touch it driving on. With
        ``behind``, the same check behind the robot (backing up)."""
        b = self.explorer.beam_angles  # the env's lidar, set at `wrap`
        if b is None:
            b = all_round_angles(ranges.size)
        x, y = ranges * np.cos(b), np.abs(ranges * np.sin(b))
        if behind:
            x = -x
        return bool(np.any((x > 0) & (x < self.clearance_stop_m) & (y < self._radius_m + 0.05)))

    def act(self, obs: dict):
        self.require_wrapped(obs)
        self.observe(obs)
        if self.continuous:
            return self.decide_continuous(obs)
        return self.encode(self.decide(obs))
