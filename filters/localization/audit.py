"""Convergence audit: before a belief calls one place certain, look for another place that
explains the recent scans as well.

A particle filter can only weigh the places it holds particles at. In a layout with look-alike
places it sometimes loses the true place to sampling (no particle near it, or too few with the
right heading) while the scans cannot yet tell the two apart, and the look-alike then gathers
all the mass: the belief says "converged", wrongly. The audit asks, at the update where the
belief would become converged, whether some pose *outside* the converged hypothesis explains
the scans of the last ``K`` measurement updates about as well as the hypothesis does:

* **window log-likelihood** `window_log_likelihood`: a pose's tempered log-likelihood summed
  over the last ``K`` updates' scans, each evaluated at the pose the odometry between the
  updates leads back to (no motion noise; the odometry of ``K`` = 20 updates, a few metres,
  drifts by centimetres);
* **the hypothesis** `best_alternative`: the highest window log-likelihood of its mean and of
  its heaviest particles, refined by a coarse-to-fine random search;
* **alternatives**: the best-fitting candidates of the filter's scan proposals
  (`filters.localization.proposals.ScanProposal`) and the heaviest particles outside the
  hypothesis, farther than ``min_dist_m`` or turned by more than ``min_heading_rad``, refined
  alike (searched less thoroughly than the alternatives, the hypothesis would look worse than it
  is, and the audit would add places that fit no better).

`filters.localization.mcl.MonteCarloLocalizer` (``MCLConfig.audit_window``) puts the best
alternative into the belief when its log ratio to the hypothesis is at least ``-margin``: particles
spread around it as the hypothesis's are around its mean (`shaped_like`, so that the two compete
on equal terms at the next updates), with the weight that ratio gives it against the hypothesis
(the two as equally likely ``K`` updates ago), at most the hypothesis's own: the audit adds
doubt, it never decides; the next updates do. The belief is then not converged, and a policy
sees a second hypothesis to tell apart.
docs/relocalizer.md, "Convergence audit", has the measurements behind the defaults.
"""

from __future__ import annotations

import dataclasses
import math
import weakref
from dataclasses import dataclass

import numba
import numpy as np

from filters.localization.likelihood_field import BeamSet, LikelihoodFieldModel, _checked_poses
from filters.mapping.grid import GridMap
from filters.pose import compose, relative, wrap_angle
from filters.robot_data.scans import LaserScan, SemanticScan
from filters.smc.resampling import inverse_cdf

Window = list[tuple[LaserScan | None, SemanticScan | None, np.ndarray, object]]
"""The scans of the last updates, oldest first, each with the odometry ``(dx, dy, dtheta)`` from
the update before it to its own (robot frame of the earlier one) and the beams the measurement
model selected from them (its ``log_likelihood_terms``' third value; None: select them again)."""

REFINE_BEST = 5
"""Poses refined in each round of the search."""
REFINE_DRAWS = 20
"""Perturbations of each, per round."""
REFINE_STEPS = ((0.2, 0.2, 0.1), (0.1, 0.1, 0.05), (0.05, 0.05, 0.025), (0.025, 0.025, 0.012), (0.01, 0.01, 0.005))
"""Standard deviations of the perturbations (m, m, rad), one round each, coarse to fine."""
REFERENCE_PARTICLES = 64
"""The hypothesis's heaviest particles (and alternatives among the particles) evaluated."""
CANDIDATES_KEPT = 50
"""Scan-proposal candidates (the best fitting the newest scans) evaluated over the window."""
PLACE_M, PLACE_RAD = 1.0, 0.5
"""Two starting poses of the local search are different places when this far apart (m) or turned (rad)."""
LOCAL_STEPS = ((0.15, 0.15, 0.08), (0.07, 0.07, 0.04), (0.03, 0.03, 0.015))
"""Standard deviations of the local search's perturbations (m, m, rad), one round each."""
LOCAL_DRAWS = 8
"""Perturbations of each place, per round of the local search."""
SCREEN_SPACING_M, SCREEN_HEADINGS = 0.3, 12
"""The screen's pose grid: every free cell this far apart (m) from the next, clear of obstacles by
`SCREEN_CLEARANCE_M`, at this many headings."""
SCREEN_CLEARANCE_M = 0.15
"""Grid poses nearer than this to an occupied cell (m) are left out: the robot cannot stand there."""
SCREEN_SIGMA_M = 0.5
"""The screen's blurred fields: lidar and semantic hit scores with this standard deviation (m; the
filter's are 0.2 and 0.3), so a grid pose 0.15 m and 0.26 rad off a place still scores it. They weigh
no negative evidence (the filter's fields, which refine the places, do)."""
SCREEN_ENTRIES = 3
"""Window entries (spread over it, the newest always) the screen scores the grid with."""
SCREEN_LIDAR_STRIDE = 2
"""The screen scores the grid with every this-many-th lidar beam of those entries (and every labelled
camera beam)."""
SCREEN_PLACES = 32
"""Places (`PLACE_M`, `PLACE_RAD` apart) the screen keeps, best first, and refines."""
SCREEN_COARSE_STEPS = ((0.15, 0.15, 0.1), (0.08, 0.08, 0.05))
"""Local-search rounds on the blurred fields (standard deviations, m, m, rad)."""
SCREEN_REFINED = 12
"""Places, the best after those rounds, refined further on the filter's own fields."""
SCREEN_FINE_STEPS = ((0.07, 0.07, 0.04), (0.03, 0.03, 0.015), (0.015, 0.015, 0.008), (0.007, 0.007, 0.004))
"""Then on the filter's own fields."""


@dataclass(frozen=True)
class Alternative:
    """The best place found outside the hypothesis.

    Attributes:
        pose: ``(3,)`` its pose (m, m, rad) at the time of the newest update.
        log_ratio: its window log-likelihood minus the hypothesis's (tempered nats).
    """

    pose: np.ndarray
    log_ratio: float


def back_steps(window: Window) -> list[np.ndarray]:
    """``(3,)`` robot-frame steps back along ``window``'s odometry, newest update first: step ``i`` takes a
    pose at the ``i``-th newest update to the pose of the update before it (``len(window) - 1`` steps)."""
    origin = np.zeros(3)
    return [relative(into, origin) for _, _, into, _ in reversed(window[1:])]


def window_scorer(model, window: Window, scale: float, steps: list[np.ndarray] | None = None):
    """``score(poses (M, 3)) -> (M,)``: `window_log_likelihood` of ``window`` with ``model`` and ``scale`` for
    any poses, its preparation done once (the steps back, and with a numba `LikelihoodFieldModel` and every
    entry's beams at hand the whole window's kernel inputs: each call is then one compiled call,
    `LikelihoodFieldModel.score_window`).

    Raises:
        ValueError: ``steps`` given, but not one step fewer than ``window`` has entries."""
    steps = back_steps(window) if steps is None else steps
    if window and len(steps) != len(window) - 1:
        raise ValueError(f"steps: need {len(window) - 1} steps back for a window of {len(window)}, got {len(steps)}")
    packed = None
    if isinstance(model, LikelihoodFieldModel) and all(e[3] is not None for e in window):  # None: numpy backend
        packed = model.packed_window([e[3] for e in reversed(window)], steps)
    if packed is not None:

        def score(poses: np.ndarray) -> np.ndarray:
            p = _checked_poses(poses)
            total = np.zeros(p.shape[0])
            model.score_window(packed, p, scale, total)
            return np.where(np.isfinite(total), total, -np.inf)

        return score
    return lambda poses: _window_log_likelihood(model, poses, window, scale, steps)


def window_log_likelihood(
    model, poses: np.ndarray, window: Window, scale: float, steps: list[np.ndarray] | None = None
) -> np.ndarray:
    """``(M,)`` tempered log-likelihood of ``window``'s scans for ``poses`` ``(M, 3)`` at the time of
    the newest update (``-inf`` where not finite).

    ``model``: ``log_likelihood_terms(poses, lidar, semantic) -> (lidar_ll, semantic_ll, beams)``
    (and, if it has one, ``beam_log_likelihoods(poses, beams, trig)``, used for entries that carry
    their beams); ``scale``: the filter's ``likelihood_scale``; ``steps``: `back_steps` of ``window``
    if the caller has them (None: computed here; ValueError if not one fewer than the entries). To score one
    window more than once, `window_scorer` prepares it once.
    """
    return window_scorer(model, window, scale, steps)(poses)


def _window_log_likelihood(model, poses: np.ndarray, window: Window, scale: float, steps: list[np.ndarray]):
    """`window_log_likelihood` entry by entry, with the model's own calls (``beam_log_likelihoods`` for entries that
    carry their beams)."""
    p = np.ascontiguousarray(poses, dtype=np.float64)
    total = np.zeros(p.shape[0])
    by_beams = getattr(model, "beam_log_likelihoods", None)
    for i, (lidar, semantic, _, beams) in enumerate(reversed(window)):
        c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
        if beams is not None and by_beams is not None:
            ll_l, ll_s = by_beams(p, beams, (c, s))
        else:
            ll_l, ll_s, _ = model.log_likelihood_terms(p, lidar, semantic)
        total += scale * (np.asarray(ll_l, dtype=np.float64) + np.asarray(ll_s, dtype=np.float64))
        if i < len(steps):  # back to the pose of the update before
            p = compose(p, steps[i], (c, s))
    return np.where(np.isfinite(total), total, -np.inf)


def outside(poses: np.ndarray, mean: np.ndarray, min_dist_m: float, min_heading_rad: float) -> np.ndarray:
    """``(N,)`` True where a pose is farther than ``min_dist_m`` from ``mean`` or turned from it by more
    than ``min_heading_rad``."""
    far = np.hypot(poses[:, 0] - mean[0], poses[:, 1] - mean[1]) > min_dist_m
    return far | (np.abs(wrap_angle(poses[:, 2] - mean[2])) > min_heading_rad)


def _heaviest(logw: np.ndarray, mask: np.ndarray, k: int) -> np.ndarray:
    idx = np.flatnonzero(mask)
    return idx[np.argsort(-logw[idx], kind="stable")[:k]]


def best_alternative(
    model,
    window: Window,
    scale: float,
    poses: np.ndarray,
    logw: np.ndarray,
    mean: np.ndarray,
    candidates: np.ndarray,
    candidate_ll: np.ndarray,
    rng: np.random.Generator,
    min_dist_m: float,
    min_heading_rad: float,
    places: int = 0,
    extra: np.ndarray | None = None,
) -> Alternative | None:
    """The pose outside the hypothesis at ``mean`` that best explains ``window`` (None if there is
    no candidate or particle outside it, or the hypothesis explains nothing finitely).

    Args:
        model, window, scale: as `window_log_likelihood`.
        poses, logw: the particle set ``(N, 3)`` and its log-weights ``(N,)``.
        mean: ``(3,)`` the hypothesis's mean pose.
        candidates: ``(C, 3)`` scan-proposal candidates; ``candidate_ll``: ``(C,)`` their
            log-likelihood of the newest scans (only their order matters).
        rng: draws the perturbations.
        min_dist_m, min_heading_rad: what counts as outside (`outside`).
        places: before the coarse-to-fine search, refine the best-fitting poses of this many different
            places each on its own (`_local_search`), on either side; 0: the coarse-to-fine search only,
            whose first round keeps the five best poses of what may be one or two places.
        extra: ``(E, 3)`` more poses to search from outside the hypothesis (`screened_places`), or None.
    """
    out = outside(poses, mean, min_dist_m, min_heading_rad)
    ref = np.vstack([mean[None], poses[_heaviest(logw, ~out, REFERENCE_PARTICLES)]])
    cand_out = outside(candidates, mean, min_dist_m, min_heading_rad)
    ll = np.where(np.isfinite(candidate_ll), candidate_ll, -np.inf)
    best_cand = np.flatnonzero(cand_out)[np.argsort(-ll[cand_out], kind="stable")[:CANDIDATES_KEPT]]
    alts = np.vstack([candidates[best_cand], poses[_heaviest(logw, out, REFERENCE_PARTICLES)]])
    if extra is not None:
        alts = np.vstack([alts, np.asarray(extra, dtype=np.float64).reshape(-1, 3)])
    if alts.shape[0] == 0:
        return None

    def is_out(p: np.ndarray) -> np.ndarray:
        return outside(p, mean, min_dist_m, min_heading_rad)

    score = window_scorer(model, window, scale)
    _, l_ref = _refined_best(score, ref, rng, lambda p: ~is_out(p), places)
    pose, l_alt = _refined_best(score, alts, rng, is_out, places)
    if not (np.isfinite(l_ref) and np.isfinite(l_alt)):
        return None
    return Alternative(pose=pose, log_ratio=float(l_alt - l_ref))


def _refined_best(score, poses: np.ndarray, rng: np.random.Generator, keep, places: int = 0):
    """``(pose, window log-likelihood)`` (``score``: a `window_scorer`) of the best pose found from ``poses`` by a
    coarse-to-fine random
    search: in each round of `REFINE_STEPS`, `REFINE_DRAWS` perturbations of each of the `REFINE_BEST`
    best poses so far, limited to those where ``keep`` is True. The hypothesis and its alternatives
    are searched alike, so neither wins by the search alone. With ``places`` the best poses of that many
    places are first refined each on its own (`_local_search`) and join the poses searched."""
    best_poses = np.asarray(poses, dtype=np.float64)
    best_ll = score(best_poses)
    if places:
        local, local_ll = _local_search(score, best_poses, best_ll, rng, keep, places)
        best_poses, best_ll = np.vstack([best_poses, local]), np.concatenate([best_ll, local_ll])
    for std in REFINE_STEPS:
        top = best_poses[np.argsort(-best_ll, kind="stable")[:REFINE_BEST]]
        tried = (top[:, None, :] + rng.normal(0.0, std, (top.shape[0], REFINE_DRAWS, 3))).reshape(-1, 3)
        tried[:, 2] = wrap_angle(tried[:, 2])
        tried = tried[keep(tried)]
        best_poses = np.vstack([best_poses, tried])
        best_ll = np.concatenate([best_ll, score(tried)])
    i = int(np.argmax(best_ll))
    return best_poses[i].copy(), float(best_ll[i])


def _distinct_places(poses: np.ndarray, ll: np.ndarray, places: int) -> list[int]:
    """Indices of the best (by ``ll``, finite only) poses of up to ``places`` different places, best first: a
    pose joins if it lies `PLACE_M` or `PLACE_RAD` from every pose already picked (`outside`'s test).

    The poses are visited in the order of a stable sort of ``-ll`` (ties: lower index first), popped lazily off
    a heap: a screen of thousands of poses usually finds its places among the first few dozen."""
    p = np.ascontiguousarray(poses, dtype=np.float64)
    return _distinct_kernel(p, np.ascontiguousarray(ll, dtype=np.float64), places, PLACE_M, PLACE_RAD).tolist()


@numba.njit(cache=True, nogil=True, inline="always")
def _before(ll, a, b):  # pragma: no cover - compiled
    """Whether pose ``a`` comes before pose ``b``: higher ``ll``, then lower index (a stable sort's order)."""
    return ll[a] > ll[b] or (ll[a] == ll[b] and a < b)


@numba.njit(cache=True, nogil=True)
def _sift_down(heap, n, i, ll):  # pragma: no cover - compiled
    while True:
        first = i
        left = 2 * i + 1
        if left < n and _before(ll, heap[left], heap[first]):
            first = left
        if left + 1 < n and _before(ll, heap[left + 1], heap[first]):
            first = left + 1
        if first == i:
            return
        heap[i], heap[first] = heap[first], heap[i]
        i = first


@numba.njit(cache=True, nogil=True)
def _distinct_kernel(poses, ll, places, place_m, place_rad):  # pragma: no cover - compiled
    heap = np.empty(ll.shape[0], dtype=np.int64)
    n = 0
    for i in range(ll.shape[0]):
        if np.isfinite(ll[i]):
            heap[n] = i
            n += 1
    for i in range(n // 2 - 1, -1, -1):
        _sift_down(heap, n, i, ll)
    picked = np.empty(places, dtype=np.int64)
    k = 0
    two_pi = 2.0 * np.pi
    while k < places and n > 0:
        i = heap[0]
        n -= 1
        heap[0] = heap[n]
        _sift_down(heap, n, 0, ll)
        alone = True
        for j in range(k):
            q = picked[j]
            far = math.hypot(poses[q, 0] - poses[i, 0], poses[q, 1] - poses[i, 1]) > place_m
            turn = abs((poses[q, 2] - poses[i, 2] + np.pi) % two_pi - np.pi) > place_rad
            if not (far or turn):
                alone = False
                break
        if alone:
            picked[k] = i
            k += 1
    return picked[:k]


def _local_search(score, poses: np.ndarray, ll: np.ndarray, rng, keep, places: int) -> tuple[np.ndarray, np.ndarray]:
    """``(poses (P, 3), window log-likelihoods (P,))`` (``score``: a `window_scorer`): the best-fitting pose of each
    of up to ``places`` different places among ``poses`` (``ll`` their window log-likelihoods; places at least
    `PLACE_M` or `PLACE_RAD` apart, best first), each refined on its own by `LOCAL_STEPS` rounds of `LOCAL_DRAWS`
    perturbations (where ``keep`` is True), so that a place whose first pose was a rough guess is not dropped for
    the near misses of a better-guessed one."""
    picked = _distinct_places(poses, ll, places)
    if not picked:
        return poses[picked].copy(), ll[picked].copy()
    return _hill_climb(score, poses[picked], rng, keep, LOCAL_STEPS, ll[picked])


def screened_places(
    model: LikelihoodFieldModel,
    window: Window,
    scale: float,
    mean: np.ndarray,
    rng: np.random.Generator,
    min_dist_m: float,
    min_heading_rad: float,
) -> np.ndarray:
    """``(P, 3)`` the best-fitting poses of up to `SCREEN_PLACES` places outside the hypothesis at ``mean``,
    found by screening the whole map, for `best_alternative`'s ``extra``.

    The scan-proposal candidates and the particles outside the hypothesis can all lie 0.3-0.9 m and
    0.2-0.5 rad from a look-alike place: too far for the window's log-likelihood, which drops by tens
    of nats within 0.1 m, to rank that place among the others, so the audit never refined it (in 6
    of the 7 wrong first convergences of the explorer on 900 tuning pairs of ``SemReloc-v8``, the true
    place explained the window as well as the hypothesis, and the audit found nothing within 4 nats).
    Here a fixed grid of poses (`pose_grid`) is scored with blurred fields (`screen_model`) on
    `SCREEN_ENTRIES` of the window's entries; the best grid pose of each of the `SCREEN_PLACES` best
    places is refined on those fields and entries (`SCREEN_COARSE_STEPS`), then the `SCREEN_REFINED`
    best of them on the model's own fields and the whole window (`SCREEN_FINE_STEPS`).
    """
    grid_poses = pose_grid(model)
    grid_poses = grid_poses[outside(grid_poses, mean, min_dist_m, min_heading_rad)]
    if grid_poses.shape[0] == 0 or not window:
        return np.zeros((0, 3))
    blurred = screen_model(model)
    short = [(lid, sem, d, _positive(b, SCREEN_LIDAR_STRIDE)) for lid, sem, d, b in _thinned(window, SCREEN_ENTRIES)]
    coarse = window_scorer(blurred, short, scale)
    picked = _distinct_places(grid_poses, coarse(grid_poses), SCREEN_PLACES)
    if not picked:
        return np.zeros((0, 3))

    def keep(p: np.ndarray) -> np.ndarray:
        return outside(p, mean, min_dist_m, min_heading_rad)

    best, ll = _hill_climb(coarse, grid_poses[picked], rng, keep, SCREEN_COARSE_STEPS)
    best = best[np.argsort(-ll, kind="stable")[:SCREEN_REFINED]]
    best, _ = _hill_climb(window_scorer(model, window, scale), best, rng, keep, SCREEN_FINE_STEPS)
    return best


def _positive(beams: BeamSet | None, lidar_stride: int = 1) -> BeamSet | None:
    """``beams`` without their negative-evidence points (the screen's blurred fields weigh none), and with
    every ``lidar_stride``-th lidar beam only (the labelled camera beams all kept)."""
    if beams is None or (not beams.n_negative and lidar_stride == 1):
        return beams
    keep = np.concatenate([np.arange(0, beams.n_lidar, lidar_stride), np.arange(beams.n_lidar, beams.lx.size)])
    return dataclasses.replace(
        beams, lx=beams.lx[keep], ly=beams.ly[keep], table=beams.table[keep], n_lidar=-(-beams.n_lidar // lidar_stride),
        nx=np.zeros(0), ny=np.zeros(0), n_starts=np.zeros(1, dtype=np.int64),
    )  # fmt: skip


def _hill_climb(score, poses: np.ndarray, rng, keep, rounds, ll=None):
    """``(poses (P, 3), window log-likelihoods (P,))`` (``score``: a `window_scorer`): each of ``poses`` moved,
    round by round of ``rounds`` (standard deviations), to the best of `LOCAL_DRAWS` perturbations of it where
    ``keep`` is True, if better (``ll``: the poses' window log-likelihoods if known)."""
    best = np.array(poses, dtype=np.float64)
    best_ll = score(best) if ll is None else np.array(ll, dtype=np.float64)
    k = best.shape[0]
    rows = np.arange(k)
    for std in rounds:
        tried = best[:, None, :] + rng.normal(0.0, std, (k, LOCAL_DRAWS, 3))
        tried[..., 2] = wrap_angle(tried[..., 2])
        flat = tried.reshape(-1, 3)
        t_ll = np.where(keep(flat), score(flat), -np.inf)
        t_ll = t_ll.reshape(k, LOCAL_DRAWS)
        j = np.argmax(t_ll, axis=1)
        better = t_ll[rows, j] > best_ll
        best[better] = tried[rows, j][better]
        best_ll[better] = t_ll[rows, j][better]
    return best, best_ll


def _thinned(window: Window, entries: int) -> Window:
    """``entries`` entries of ``window`` spread over it (the oldest and the newest among them), each with
    the odometry composed since the entry kept before it (so `back_steps` follows the same path)."""
    n = len(window)
    if n <= entries:
        return window
    kept = set(np.round(np.linspace(0, n - 1, entries)).astype(int).tolist())
    out: Window = []
    since = None
    for i, (lidar, semantic, delta, beams) in enumerate(window):
        since = np.asarray(delta, dtype=np.float64) if since is None else compose(since[None], delta[None])[0]
        if i in kept:
            out.append((lidar, semantic, since if out else np.zeros(3), beams))
            since = None
    return out


_pose_grids: weakref.WeakKeyDictionary[GridMap, np.ndarray] = weakref.WeakKeyDictionary()


def pose_grid(model: LikelihoodFieldModel) -> np.ndarray:
    """``(G, 3)`` read-only: the screen's poses on ``model``'s map (free cells `SCREEN_SPACING_M` apart and
    `SCREEN_CLEARANCE_M` clear of obstacles, `SCREEN_HEADINGS` headings each), computed once per map."""
    grid = model.grid
    got = _pose_grids.get(grid)
    if got is None:
        stride = max(1, round(SCREEN_SPACING_M / grid.resolution_m))
        ok = grid.free_mask() & (model.distance_fields_m[0] >= SCREEN_CLEARANCE_M)
        rows, cols = np.nonzero(ok[::stride, ::stride])
        xy = grid.cell_centers(rows * stride, cols * stride)
        headings = -np.pi + (np.arange(SCREEN_HEADINGS) + 0.5) * (2.0 * np.pi / SCREEN_HEADINGS)
        got = np.empty((xy.shape[0], SCREEN_HEADINGS, 3))
        got[..., :2] = xy[:, None, :]
        got[..., 2] = headings
        got = got.reshape(-1, 3)
        got.setflags(write=False)
        _pose_grids[grid] = got
    return got


_screen_models: weakref.WeakKeyDictionary[LikelihoodFieldModel, LikelihoodFieldModel] = weakref.WeakKeyDictionary()


def screen_model(model: LikelihoodFieldModel) -> LikelihoodFieldModel:
    """``model`` with its lidar and semantic hit scores blurred to `SCREEN_SIGMA_M` and no negative evidence
    (`LikelihoodFieldModel.reconfigured`: its distance fields are the model's), built once per model and
    kept while the model lives (not in `cached_model`'s few slots, which envs on many layouts would make it
    rebuild at each audit)."""
    got = _screen_models.get(model)
    if got is None:
        blur = {}
        for name, cfg in (("lidar", model.lidar_config), ("semantic", model.semantic_config)):
            blur[name] = dataclasses.replace(cfg, sigma_hit_m=max(cfg.sigma_hit_m, SCREEN_SIGMA_M))
        got = model.reconfigured(blur["lidar"], blur["semantic"])
        _screen_models[model] = got
    return got


def shaped_like(
    poses: np.ndarray,
    weights: np.ndarray,
    mean: np.ndarray,
    at: np.ndarray,
    m: int,
    rng: np.random.Generator,
    min_dist_m: float,
    min_heading_rad: float,
) -> np.ndarray:
    """``(m, 3)`` poses around ``at`` spread as the hypothesis's particles are around ``mean``: ``m``
    particles not `outside` the hypothesis, drawn by weight (systematic pointers), each carried by
    the rigid motion that takes ``mean`` to ``at`` (their offsets in ``mean``'s frame kept)."""
    inside = np.flatnonzero(~outside(poses, mean, min_dist_m, min_heading_rad))
    total = weights[inside].sum() if inside.size else 0.0
    if not total > 0.0:  # nothing near the mean carries weight: all at ``at``
        return np.tile(np.asarray(at, dtype=np.float64), (m, 1))
    w = weights[inside] / total
    pick = inside[inverse_cdf(w, (rng.random() + np.arange(m)) / m)]
    return compose(np.broadcast_to(at, (m, 3)), relative(mean, poses[pick]))
