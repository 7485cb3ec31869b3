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

from dataclasses import dataclass

import numpy as np

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


def window_log_likelihood(
    model, poses: np.ndarray, window: Window, scale: float, steps: list[np.ndarray] | None = None
) -> np.ndarray:
    """``(M,)`` tempered log-likelihood of ``window``'s scans for ``poses`` ``(M, 3)`` at the time of
    the newest update (``-inf`` where not finite).

    ``model``: ``log_likelihood_terms(poses, lidar, semantic) -> (lidar_ll, semantic_ll, beams)``
    (and, if it has one, ``beam_log_likelihoods(poses, beams, trig)``, used for entries that carry
    their beams); ``scale``: the filter's ``likelihood_scale``; ``steps``: `back_steps` of ``window``
    if the caller scores it more than once (None: computed here).
    """
    p = np.ascontiguousarray(poses, dtype=np.float64)
    total = np.zeros(p.shape[0])
    steps = back_steps(window) if steps is None else steps
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
    """
    out = outside(poses, mean, min_dist_m, min_heading_rad)
    ref = np.vstack([mean[None], poses[_heaviest(logw, ~out, REFERENCE_PARTICLES)]])
    cand_out = outside(candidates, mean, min_dist_m, min_heading_rad)
    ll = np.where(np.isfinite(candidate_ll), candidate_ll, -np.inf)
    best_cand = np.flatnonzero(cand_out)[np.argsort(-ll[cand_out], kind="stable")[:CANDIDATES_KEPT]]
    alts = np.vstack([candidates[best_cand], poses[_heaviest(logw, out, REFERENCE_PARTICLES)]])
    if alts.shape[0] == 0:
        return None

    def is_out(p: np.ndarray) -> np.ndarray:
        return outside(p, mean, min_dist_m, min_heading_rad)

    steps = back_steps(window)
    _, l_ref = _refined_best(model, window, scale, ref, rng, lambda p: ~is_out(p), steps, places)
    pose, l_alt = _refined_best(model, window, scale, alts, rng, is_out, steps, places)
    if not (np.isfinite(l_ref) and np.isfinite(l_alt)):
        return None
    return Alternative(pose=pose, log_ratio=float(l_alt - l_ref))


def _refined_best(
    model,
    window: Window,
    scale: float,
    poses: np.ndarray,
    rng: np.random.Generator,
    keep,
    steps: list[np.ndarray],
    places: int = 0,
):
    """``(pose, window log-likelihood)`` of the best pose found from ``poses`` by a coarse-to-fine random
    search: in each round of `REFINE_STEPS`, `REFINE_DRAWS` perturbations of each of the `REFINE_BEST`
    best poses so far, limited to those where ``keep`` is True. The hypothesis and its alternatives
    are searched alike, so neither wins by the search alone. With ``places`` the best poses of that many
    places are first refined each on its own (`_local_search`) and join the poses searched."""
    best_poses = np.asarray(poses, dtype=np.float64)
    best_ll = window_log_likelihood(model, best_poses, window, scale, steps)
    if places:
        local, local_ll = _local_search(model, window, scale, best_poses, best_ll, rng, keep, steps, places)
        best_poses, best_ll = np.vstack([best_poses, local]), np.concatenate([best_ll, local_ll])
    for std in REFINE_STEPS:
        top = best_poses[np.argsort(-best_ll, kind="stable")[:REFINE_BEST]]
        tried = (top[:, None, :] + rng.normal(0.0, std, (top.shape[0], REFINE_DRAWS, 3))).reshape(-1, 3)
        tried[:, 2] = wrap_angle(tried[:, 2])
        tried = tried[keep(tried)]
        best_poses = np.vstack([best_poses, tried])
        best_ll = np.concatenate([best_ll, window_log_likelihood(model, tried, window, scale, steps)])
    i = int(np.argmax(best_ll))
    return best_poses[i].copy(), float(best_ll[i])


def _local_search(
    model, window: Window, scale: float, poses: np.ndarray, ll: np.ndarray, rng, keep, steps, places: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(poses (P, 3), window log-likelihoods (P,))``: the best-fitting pose of each of up to ``places``
    different places among ``poses`` (``ll`` their window log-likelihoods; places at least `PLACE_M` or
    `PLACE_RAD` apart, best first), each refined on its own by `LOCAL_STEPS` rounds of `LOCAL_DRAWS`
    perturbations (where ``keep`` is True), so that a place whose first pose was a rough guess is not
    dropped for the near misses of a better-guessed one."""
    order = np.argsort(-np.where(np.isfinite(ll), ll, -np.inf), kind="stable")
    picked: list[int] = []
    for i in order:
        if len(picked) == places or not np.isfinite(ll[i]):
            break
        if picked and not outside(poses[picked], poses[i], PLACE_M, PLACE_RAD).all():
            continue
        picked.append(int(i))
    best, best_ll = poses[picked].copy(), ll[picked].copy()
    k = len(picked)
    if k == 0:
        return best, best_ll
    rows = np.arange(k)
    for std in LOCAL_STEPS:
        tried = best[:, None, :] + rng.normal(0.0, std, (k, LOCAL_DRAWS, 3))
        tried[..., 2] = wrap_angle(tried[..., 2])
        flat = tried.reshape(-1, 3)
        t_ll = np.where(keep(flat), window_log_likelihood(model, flat, window, scale, steps), -np.inf)
        t_ll = t_ll.reshape(k, LOCAL_DRAWS)
        j = np.argmax(t_ll, axis=1)
        better = t_ll[rows, j] > best_ll
        best[better] = tried[rows, j][better]
        best_ll[better] = t_ll[rows, j][better]
    return best, best_ll


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
