"""Semantic Monte Carlo relocalizer (paper 004 §3, on top of AMCL-style MCL).

Model and algorithm are separate (``nchopin/particles`` style):

* motion model: `filters.motion.odometry.OdometryMotionModel` (``sample(poses, delta, rng)``),
* measurement model: `filters.localization.likelihood_field.LikelihoodFieldModel`
  (``log_likelihood(poses, lidar, semantic) -> (N,)``; lidar field x per-class
  semantic field, paper 004 Eq. 8),
* the filter loop: `MonteCarloLocalizer` below, which owns an ``(N, 3)``
  pose array and ``(N,)`` log-weights (normalised with log-sum-exp).

Semantics of one `MonteCarloLocalizer.update` (see ``docs/relocalizer.md``):

1. **Motion gate (AMCL).** `predict` moves the particles
   on every call and accumulates the odometry since the last measurement update.
   The measurement update itself is *skipped* (returns diagnostics with
   ``updated=False``) unless the robot moved more than ``update_min_d_m`` or turned
   more than ``update_min_a_rad`` since the last update — exactly as AMCL skips the
   filter update. The first update after an ``init_*`` always runs, as does
   ``update(..., force=True)``. With both thresholds 0 every call updates. Repeated
   scans from a standing robot would otherwise be multiplied in as if independent.
2. **Weighting.** ``logw += likelihood_scale * (lidar_ll + semantic_ll)``; the
   semantic factor is left out when ``use_semantic`` is False or no semantic scan
   is given. Non-finite log-likelihoods (possible only with a custom measurement
   model) count as ``-inf``.
3. **Underflow recovery.** If no particle has a finite log-weight left, the
   filter re-initialises globally (uniform over free space), sets
   ``diagnostics.recovered = True`` and returns; weights never become NaN. (The
   likelihood-field model itself is evaluated in log space with a finite floor,
   so normal scans cannot trigger this however unlikely they are.)
4. **Resampling**, with the scheme named ``resampler``, when ``ESS < resample_ess_frac * N``
   and the semantic hold-off is over: with ``use_semantic`` and
   ``holdoff_min_detections > 0``, no resampling until that many object detections
   (runs of equally-labelled beams, `filters.localization.likelihood_field.count_detections`)
   were seen since the last ``init_*`` (paper 004 §3: keep diversity until several
   objects were seen). Since updates only run after enough motion, resampling also
   only happens after motion (paper 004's threshold).
5. **KLD-sampling** (Fox 2003), if ``kld``: instead of N draws with ``resampler``,
   particles are drawn i.i.d. from the weights (multinomial, as in Fox's algorithm)
   one by one until ``n >= n_chi(k)`` where ``k`` is the number of occupied
   ``kld_bin_xy_m x kld_bin_xy_m x kld_bin_theta_rad`` bins so far and
   ``n_chi(k) = (k - 1) / (2 eps) * (1 - 2/(9(k-1)) + sqrt(2/(9(k-1))) z)^3``,
   clipped to `MonteCarloLocalizer.kld_bounds` (``[min_particles, max_particles]``; an
   explicit ``n_particles`` is the upper bound instead; clustered resampling's floors, step 6, can
   add to it). Vectorised: ``max(2 N, 4 min_particles)``
   draws (all ``max_particles`` if the bound is not met within them), then the first prefix
   length that satisfies the bound.
6. **Clustered resampling** (after the clustered particle filter of Milstein et al. 2002),
   if ``resample_mode == "clustered"``: the particles are split into the clusters of
   `filters.localization.belief.cluster_labels`; every cluster whose weight is at least
   ``cluster_keep_weight`` keeps its weight and gets
   ``max(floor, round(n_new * weight))`` particles (``floor = min(cluster_min_particles,
   n_new // kept clusters)``), drawn from its own
   particles with ``resampler``; lighter clusters are dropped. A hypothesis that the
   sensors still support is never lost to resampling noise; ``n_new`` is the count drawn at
   the last init (or the KLD count). The floors come on top of the proportional shares, so a
   resampled set can hold more than ``n_new``: at most ``n_new`` plus ``floor`` per kept
   cluster (plus rounding), never more than about ``2 n_new``; it does not grow from one
   resampling to the next. For an exact particle count use ``resample_mode="global"``.
7. **Augmented MCL** (Thrun et al. Table 8.3, with AMCL ``pf.c``'s semantics), if
   ``augmented``: every update computes ``w_avg = sum_i W_i * exp(ll_i / n_beams)`` (prior
   weights ``W``, the per-beam geometric-mean likelihood, so it is scale-free in the beam
   count and cannot underflow), then ``w_slow += alpha_slow (w_avg - w_slow)``,
   ``w_fast += alpha_fast (w_avg - w_fast)``, each average *starting at the first* ``w_avg``
   (after every init and every injection, as ``pf.c``). Every update then replaces each
   particle, with probability ``max(0, 1 - w_fast / w_slow)``, by an injected one (weight
   ``1 / N`` before renormalising), and resets both averages after an injection.
   Injected particles come from ``injection``: ``"uniform"`` (free space) or ``"scan"``
   (`filters.localization.proposals`: ``proposal_candidates`` candidates, about
   ``proposal_semantic_frac`` of them from the current semantic detections, the rest
   uniform, drawn in proportion to their tempered likelihood of the current scans).
8. **Evidence limits.** ``max_update_log_ratio`` caps how far below the best particle one
   update can push any particle (tempered log-likelihoods are clipped to
   ``max - max_update_log_ratio``), so no single scan settles a case by itself; with
   ``lidar_on_rotation=False`` the lidar factor is left out of updates triggered by
   rotation alone (a 360 deg lidar sees the same scene when the robot turns in place, so
   its correlated errors would be multiplied in again and again); the semantic factor
   (a narrow camera, which does see new things when turning) is always used.
9. **Convergence audit**, if ``audit_window`` (after ``init_global``, and with ``audit_after_surprise`` after a
   surprise, step 10, or with ``audit_after_lost_hold`` after a held convergence ends without one, until the
   next init or, with ``audit_after_surprise_once``, until it clears a convergence): at each update after
   which the set meets the "converged" criterion and did not before (a place an audit cleared is
   not audited again for ``audit_window`` updates), a pose outside the converged hypothesis
   that explains the last ``audit_window`` updates' scans within ``audit_margin`` (tempered nats)
   of it becomes a second hypothesis (`filters.localization.audit`; docs/relocalizer.md). With
   ``audited_convergence`` the belief is called converged only after such an update: a set that
   comes to meet the criterion between updates (a prediction alone) waits for the next update's audit.
10. **Surprise**, if ``surprise_ratio``: once the belief has been converged since the last init, an
   update with the lidar whose scans fit the particles far worse than of late (``w_avg <
   surprise_ratio * w_fast``, the augmented-MCL averages) is taken for a jump the odometry did not
   see (a kidnapping, a slip; with ``surprise_own_average`` the test keeps an average of its own,
   which injections do not restart): a held convergence (``belief.converged_hold_weight``) ends, the
   audit's window drops the scans before it and the next convergence, or the current one, is audited.

Particle counts: ``init_global`` and ``init_around`` draw ``n_particles``. With
``n_particles=None`` the count follows the map: ``init_global`` draws
``global_particles_per_m2`` times the map's free area, clipped to ``[min_particles,
max_particles]``, so a larger map gets more particles, and ``init_around`` draws
``min_particles`` (a tight cloud needs no more); KLD sampling then adapts the count as the
belief concentrates or spreads.
"""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, fields, replace

import numpy as np
from scipy.special import logsumexp

from filters import _blas
from filters.localization import audit, belief_kernels, kld_kernels
from filters.localization.belief import (
    MIN_BIN_THETA_RAD,
    Belief,
    BeliefConfig,
    Hypothesis,
    carried,
    cluster_labels,
    holds_as_converged,
    linear_bin_keys,
    summarize,
)
from filters.localization.likelihood_field import (
    DEFAULT_SEMANTIC_FIELD,
    NO_NEGATIVE_EVIDENCE,
    LikelihoodFieldConfig,
    LikelihoodFieldModel,
    NegativeEvidenceConfig,
)
from filters.localization.proposals import ScanProposal, prior_mass_near
from filters.mapping.grid import GridMap
from filters.motion.odometry import OdometryMotionConfig, OdometryMotionModel
from filters.numbers import MAX_LENGTH_M, is_int, is_real
from filters.pose import compose, finite_increment, wrap_angle
from filters.robot_data.scans import LaserScan, SemanticScan
from filters.smc.logsumexp import logsumexp as fast_logsumexp
from filters.smc.resampling import RESAMPLERS, closed_cdf, get_resampler, inverse_cdf

_MAX_DENSE_KEYS = 8_000_000
"""Most KLD bins the fast path's dense table of occupied bins may span (else the reference runs)."""


def _fox_bound(k, epsilon: float, z: float) -> np.ndarray:
    """Fox's KLD-sampling bound ``n_chi(k)`` (float array) for ``k`` occupied bins."""
    k = np.asarray(k, dtype=np.float64)
    km1 = np.maximum(k - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    n = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(k > 1, n, 1.0)


@functools.lru_cache(maxsize=8)
def _fox_bound_table(epsilon: float, z: float, size: int) -> np.ndarray:
    """``_fox_bound(k)`` for ``k = 0 .. size - 1``, read-only."""
    table = _fox_bound(np.arange(size), epsilon, z)
    table.setflags(write=False)
    return table


MAX_AUDIT_WINDOW = 1000
"""Most measurement updates `MCLConfig.audit_window` may look back over."""
MAX_AUDIT_PLACES = 256
"""Most places `MCLConfig.audit_places` may refine one by one."""

_SUBCONFIGS = {
    "lidar_field": LikelihoodFieldConfig,
    "semantic_field": LikelihoodFieldConfig,
    "negative_evidence": NegativeEvidenceConfig,
    "motion": OdometryMotionConfig,
    "belief": BeliefConfig,
}


BELIEF_BETWEEN_UPDATES = ("exact", "odometry")
"""The values of `MCLConfig.belief_between_updates`."""

MIN_KLD_BIN_XY_M = 1e-3
"""Narrowest position bin of KLD sampling (m): far below any useful bin, and wide enough that the bin indices of poses
as far as maps reach fit an int64."""
MAX_PARTICLES = 10_000_000
"""Upper bound of every particle count (a filter of 10 million particles holds ~320 MB of poses
and weights before any per-beam work): larger counts are refused, not left to a MemoryError."""


@dataclass(frozen=True)
class MCLConfig:
    """Configuration of `MonteCarloLocalizer` (units in the names).

    Sub-configs may be given as dicts (e.g. from ``gym.make`` keyword arguments);
    unknown keys raise ``TypeError`` there as here.

    Attributes:
        n_particles: particles drawn by ``init_global`` / ``init_around``; None = sized by the map
            (module docstring). With KLD it is the upper bound of each KLD draw; clustered
            resampling can add up to ``cluster_min_particles`` per kept cluster to a set (module
            docstring, step 6).
        lidar_field: lidar likelihood field.
        semantic_field: per-class semantic likelihood fields.
        negative_evidence: evidence from mapped objects the camera did not see
            (`NegativeEvidenceConfig`; off by default, on in ``SemReloc-v4`` to ``-v7``).
        motion: odometry motion noise.
        belief: bins and thresholds of `MonteCarloLocalizer.belief`.
        use_semantic: multiply in the semantic factor (False = lidar-only MCL).
        likelihood_scale: exponent on the measurement likelihood (1 = plain Bayes). The
            default 0.1 tempers 60 beams that are far from independent (AMCL's ``p^3``
            sum is another fix for the same problem): with plain Bayes one scan decides
            between look-alike places before the semantic factor can, see docs/relocalizer.md.
        update_min_d_m, update_min_a_rad: motion gate of the measurement update (AMCL).
        resampler: name in `filters.smc.resampling.RESAMPLERS`. A draw of another count than the set's
            (KLD; a cluster's share; without KLD, back to the budget after an audit added particles) uses
            systematic pointers.
        resample_ess_frac: resample when ESS < this fraction of N (1.0 = every update).
        holdoff_min_detections: semantic hold-off (0 = off).
        kld: KLD-sampling (Fox 2003): the particle count adapts to the belief's spread.
        kld_bin_xy_m, kld_bin_theta_rad: its histogram bins (m, rad).
        kld_epsilon, kld_z: its error bound and the upper standard normal quantile (2.326 for
            1 - delta = 0.99).
        kld_one_sequence: True: a draw that has not met Fox's bound within its first ``max(2 N, 4 min_particles)``
            draws goes on with the same sequence up to the upper bound (Fox 2003's algorithm: one sequence, stopped
            where the bound is first met). False (every registered env before ``SemReloc-v22``): it draws again from
            scratch, a second sequence that can stop sooner, which moves the set size down and loosens the bound.
        min_particles, max_particles: with ``n_particles`` None, the bounds of ``init_global``'s
            map-sized count, ``init_around`` draws ``min_particles``, and KLD draws at most
            ``max_particles`` (clustered resampling's per-cluster floors can add to a set, so
            counts are not clipped to these bounds; see the module docstring).
        global_particles_per_m2: particles per m^2 of free space for ``init_global`` when
            ``n_particles`` is None (> 0 then).
        resample_mode: ``"global"`` (one draw over all particles) or ``"clustered"``.
        cluster_keep_weight, cluster_min_particles: clustered resampling (module docstring).
        augmented, alpha_slow, alpha_fast: augmented MCL random-particle injection.
        injection: ``"uniform"`` or ``"scan"``: where injected particles come from.
        proposal_candidates, proposal_semantic_frac: the scan proposal's candidate count and
            the fraction drawn from semantic detections.
        proposal_frac: at least this fraction of the particles is replaced by injected ones at
            every update (Mixture MCL; 0 = only augmented MCL injects).
        proposal_weight: weight of each routine injected particle, as a fraction of ``1 / N``
            (before renormalising). An update whose augmented-MCL probability exceeds
            ``proposal_frac`` is a recovery and gives all its injected particles ``1 / N``; a
            smaller one is absorbed into the routine injection. Below 1 the fresh particles start
            lighter than an average one (docs/relocalizer.md: 0.2 did not help).
        proposal_prior_weight: ``lam`` in ``[0, 1]``: each routine injected particle's weight is
            scaled by ``1 - lam + lam * near``, ``near`` the prior belief's weight within the
            particle's cluster bin (``belief.cluster_bin_m`` x ``belief.cluster_bin_theta_rad``)
            and the 26 bins around it (fewer with under 3 heading bins; in ``[0, 1]``; Mixture
            MCL weighs its sensor-drawn samples by the prior, Thrun et al. 2001). 0 (every registered env): all at
            ``proposal_weight / N``, so a look-alike place the belief has left is refilled at
            every update; 1: a proposal where the belief holds nothing gets weight 0. More than
            0 keeps a tracked belief and converges sooner, but rescues a wrong convergence less
            often (docs/relocalizer.md, "Proposals weighed by the prior"). Recovery injections
            are never scaled.
        proposal_candidates_per_particle: ``r``: a routine injection of ``m`` particles weighs
            ``min(proposal_candidates, max(10 r, r m))`` scan-proposal candidates and draws its particles among them
            by their likelihood (20: ``max(200, 20 m)``, every registered env, ``SemReloc-v22`` included; each term
            rounded down; weighing the candidates is most of an injection's cost).
        audit_window: ``K`` (0 = off): the *convergence audit* (`filters.localization.audit`). At
            an update after which the set meets the "converged" criterion and did not before, it
            looks for the pose outside the converged hypothesis that best explains the scans of the
            last ``K`` updates (followed back along the odometry); if that pose's tempered
            log-likelihood of them is at most ``audit_margin`` below the hypothesis's, it adds
            ``cluster_min_particles`` particles there, shaped like the hypothesis
            (`filters.localization.audit.shaped_like`) and together weighing the hypothesis's
            weight times the likelihood ratio (at most 1), so the belief holds two hypotheses,
            not one. Only
            after `init_global` (the audit weighs the two places as equally likely ``K`` updates
            ago; after `init_around` the caller said where the robot is). A hypothesis an audit
            cleared is not audited again at the same place (within ``2 * belief.cluster_bin_m``
            and ``belief.cluster_bin_theta_rad`` of it) for ``K`` updates, when the belief
            drops out of "converged" and back.
        audit_margin: how far below the hypothesis (tempered nats, >= 0) an alternative may fit
            and still be added.
        audit_candidates: scan-proposal candidates the audit draws (the best 50 outside the
            hypothesis are evaluated over the window, with the heaviest particles outside it).
        audit_candidates_per_m2: at least this many candidates per m^2 of the map's free space (more
            than ``audit_candidates`` on large maps, so they cover a large hall as densely as a small
            one; at most `MAX_PARTICLES`); 0 (before ``SemReloc-v7``): ``audit_candidates`` on any map.
        audit_places: before its coarse-to-fine search, the audit refines the best-fitting poses of this
            many different places on each side on their own (`filters.localization.audit._local_search`),
            so that a look-alike place whose candidates were rough guesses is not dropped for the near
            misses of another; 0 (before ``SemReloc-v7``): the coarse-to-fine search only.
        audit_screen: the audit also screens the whole map for alternatives
            (`filters.localization.audit.screened_places`: a pose grid scored with blurred fields, the
            best places refined), so a look-alike place no candidate or particle lies near is still
            found; needs the model to be a `LikelihoodFieldModel`. False before ``SemReloc-v9``.
        audit_screen_pause: after an audit whose screen found no place within ``audit_margin``, the
            audits of the next this-many updates search without it (the first audit after an init, a
            surprise or an audit that added a place always screens): a belief that stays at a place the
            screen cleared is audited again each time it comes back to "converged", and the screen would
            find nothing new (0: every audit screens).
        audit_screen_pause_place: the pause holds only while the hypothesis stays at the place that
            screen cleared (its mean carried along the odometry since; farther than the audit's
            ``outside`` limits: screen again). False before ``SemReloc-v10`` (v9's pause ignored where the
            belief was). The mean is carried without motion noise, as `filters.pose.compose` moves a pose.
        audit_blur_margin: with the screen on, an alternative the audit found more than ``audit_margin``
            below the hypothesis on the filter's fields is kept anyway when, on the screen's blurred fields
            (`filters.localization.audit.screen_model`), it is at most this far below it (tempered nats;
            0: off; needs ``audit_screen`` and ``audit_window``): its particles are added with the weight the
            blurred ratio gives it (which the update's ``audit_log_ratio`` then reports), and the belief is
            not converged. The hypothesis is scored there at its mean, not refined. Two places alike in the
            world differ in a map a robot built (the mapping drive saw them from other poses, with noise):
            cell-sized differences the filter's fields read as several nats over a window, the blurred ones
            hardly. Off in every env (on a fifth outside tester's corridor pods 1.0 removed the wrong
            convergences, 2 of 180 episodes, and 27 % of the successes; it cost the viewpoint planner 13 of
            890 successes on 900 tuning pairs and 12 of 915 on the 930 held-out ones: docs/relocalizer.md,
            "Corridor pods").
        audited_convergence: with the audit on, the belief is called converged only after an update
            that audited it (or kept a convergence an update audited): a set that comes to meet the
            criterion between updates (a prediction moving particles from one cluster to another)
            waits for the next update's audit. False (before ``SemReloc-v7``): it was called converged
            at once, and audited only at the next update.
        surprise_ratio: in ``[0, 1)`` (0 = off): the *surprise* test (module docstring, step 10). After
            the belief has been converged once since the last init, an update that used the lidar and
            whose average beam likelihood ``w_avg`` falls below ``surprise_ratio`` times ``w_fast`` (the
            augmented-MCL averages, kept for this test also when ``augmented`` is off, which then only
            leaves out the recovery injection) ends a held convergence (that update is judged by the
            95 % rule alone), empties the audit window (keeping this update's scans), forgets the place
            the audit last cleared, and has the audit run at the next update whose set meets the
            "converged" criterion, this one included. Particles and weights are touched only by that
            audit. ``UpdateDiagnostics.surprise`` records it.
        audit_after_surprise: a surprise also turns the convergence audit on after ``init_around`` (tracking),
            where it is otherwise off, until the next init (or, with ``audit_after_surprise_once``, until it has
            cleared a convergence): a filter that lost its pose (a kidnapping) and
            converges again has relocalized globally, and that convergence gets the audit a global start's
            gets. False before ``SemReloc-v12``: in a tracking episode no convergence was audited, and after a
            kidnapping in an outside tester's four-fold symmetric hall the explorer's belief converged at a
            quarter-turned image of the truth in 5 of 16 episodes (docs/relocalizer.md, "After a kidnapping").
            Needs ``surprise_ratio`` and ``audit_window``.
        audit_after_surprise_once: the audit a surprise turned on (``audit_after_surprise``, in a tracking
            episode) turns off again once it has cleared a convergence: the pose is found again, and the tracking
            episode goes on as before its surprise. False before ``SemReloc-v15``: the audit stayed on until the
            next init, and at each later convergence a window of scans without a telling object let it add a
            look-alike place to a belief that had converged again at the truth (docs/relocalizer.md, "After a
            surprise, an audit until it clears"). Needs ``audit_after_surprise``.
        audit_after_lost_hold: a held convergence that ends without a surprise (its hypothesis falls below
            ``belief.converged_hold_weight`` or leaves its place, and the belief is not converged elsewhere)
            also turns the audit on in a tracking episode, as a surprise does (and off again as
            ``audit_after_surprise_once`` says): a kidnapping the surprise tests miss loses the hold all the
            same, and the next convergence is a relocalization. The audit's window is kept while the audit is
            off, so its first audit judges the last ``audit_window`` updates' scans (a surprise, by contrast,
            drops the scans before it). False before
            ``SemReloc-v16``: after such a kidnapping the belief converged again unaudited, in an outside
            tester's pillar hall and class-only rooms at a look-alike place in 10-40 % of episodes
            (docs/relocalizer.md, "A hold lost without a surprise"). Needs ``audit_window`` and
            ``belief.converged_hold_weight``.
        hold_init_pose: ``init_around`` holds its ``pose`` as a converged hypothesis (``belief.converged_hold_weight``
            decides, as after an update called converged) and arms the surprise tests, as a convergence does: a
            tracking start is told its pose, so it is converged at that pose from the first update on, and a
            kidnapping before the set first met the 95 % rule by itself is still noticed (a surprise, or with
            ``audit_after_lost_hold`` a lost hold). Meant for a pose known to be right (the envs' tracking starts
            give the true pose): a wrong ``pose`` is called converged until the hold is lost. False before
            ``SemReloc-v17``: a tracking start whose cloud split into hypotheses (about 94 % in the heaviest) was not
            converged, had no hold to lose and no surprise test armed, and a kidnapping then could converge again,
            unaudited, at a look-alike place (docs/relocalizer.md, "A tracking start holds its pose").
            Needs ``belief.converged_hold_weight``.
        places_follow_odometry: the places the filter remembers between updates, a held convergence's
            (``belief.converged_hold_weight``) and the last one an audit cleared (``audit_window``), move with the
            odometry at each ``predict``, as the screen's pause does (``audit_screen_pause_place``), so they stay
            on the robot's track. True from ``SemReloc-v19`` on; False in ``SemReloc-v1`` to ``-v18`` (which keep their
            episodes): there they stay where the last update left them, so a hold lapses, and a cleared place is audited
            again, once the robot has moved 1 m or turned 45 deg between the updates that compare them (at the
            envs' speeds a hold never moves that far between two updates; a robot whose scans come that far
            apart needs True).
        lost_hold_window: ``M`` (0 = off): when a held convergence ends without a surprise (``audit_after_lost_hold``),
            the audit's window keeps only the scans of the updates after the last one whose set met the "converged"
            criterion by itself (the hold's fade), and the audit judges a convergence only once the window holds at
            least ``M`` scans (until then the belief is not called converged). The scans before the fade fit the held
            place: after an unnoticed kidnapping they come from before it and testify for the old track, which
            v16 and v17 let the audit judge on (docs/relocalizer.md, "The window's old scans"). If no scan in the
            window met the criterion by itself (the fade began before the window), the whole window is kept. 0 before
            ``SemReloc-v18``. Needs ``audit_after_lost_hold`` and ``audited_convergence`` (which holds "converged"
            back until an audit has judged), and ``M <= audit_window``.
        surprise_own_average: the surprise test compares with an average of its own: the fast average
            (``alpha_fast``) of ``w_avg`` over every update with beams, as ``w_fast``, but restarted at a surprise and
            never by an injection. False before ``SemReloc-v13``: it compared with the augmented-MCL
            ``w_fast``, which ``pf.c``'s rule restarts after every update whose ``w_fast`` fell below
            ``w_slow`` by any amount; a restarted average starts at the next update's ``w_avg``, so a
            kidnapping right after a restart, or after turn-in-place updates without the lidar, set the
            new normal instead of raising a surprise (all three kidnappings after which v12's belief
            converged at a wrong place, docs/relocalizer.md, "The surprise test's own average").
            Needs ``surprise_ratio``.
        semantic_surprise_ratio: in ``[0, 1)`` (0 = off): the camera's own surprise test. Once the belief has
            been converged since the last init, an update with at least ``semantic_surprise_min_beams`` labelled
            camera beams whose average semantic likelihood per labelled beam ``w_sem`` (the particles' prior
            weights times ``exp(semantic_ll / n_semantic)``, negative evidence included) falls below
            ``semantic_surprise_ratio`` times the fast average (``alpha_fast``) of ``w_sem`` over the earlier such
            updates is *low*; ``semantic_surprise_updates`` low updates in a row (an update with fewer labelled
            beams breaks the run) are a surprise too, with every consequence of ``surprise_ratio``'s. It sees a
            kidnapping that only the objects' classes reveal (the same walls and furniture shapes, other
            classes), which the all-beam test misses: there the lidar's beams outnumber the labelled camera
            beams. The average restarts at any surprise, at that update's ``w_sem`` (or, if it
            was not judged, at the next judged update's, which is not compared). Off before
            ``SemReloc-v14``. Needs ``surprise_ratio`` and ``surprise_own_average``.
        semantic_surprise_min_beams: labelled camera beams an update needs to be judged by (and to enter the
            average of) the semantic surprise test: a few beams on one object average too noisily.
        semantic_surprise_updates: low updates in a row the semantic surprise test needs: one alone is what a
            mislabelled detection looks like (about 6 % of judged updates while tracking in the built-in layouts;
            docs/relocalizer.md, "A surprise test of the camera's own").
        max_update_log_ratio: cap on one update's tempered log-likelihood spread (inf = none).
        lidar_on_rotation: use the lidar factor in updates triggered by rotation alone.
        backend: ``"numba"`` or ``"numpy"`` (reference) measurement kernel.
        fast_path: numba kernels for the belief summary, the clustering of clustered resampling
            and the filter's bookkeeping (True), or the NumPy reference code (False). Unlike
            ``backend`` this changes nothing but speed: both give the same particles, weights,
            diagnostics and beliefs bit for bit (``tests/test_fast_path.py``).
        belief_between_updates: what `MonteCarloLocalizer.belief` reports after a ``predict`` that no update has
            followed yet (the motion gate, ``update_min_d_m`` / ``update_min_a_rad``, skips most control steps):
            ``"exact"`` (default) the summary of the moved set, computed again at every step; ``"odometry"`` the
            summary of the set the last update (or init) left, carried by the odometry since
            (`filters.localization.belief.carried`: means composed with it, covariances through its Jacobian, no
            motion noise added), as AMCL reports its pose between updates. The particles, weights, updates and
            random draws are the same either way (only the reported belief differs between updates); ``"odometry"``
            skips the summary, about a third of such a step's cost (docs/performance.md).
        predict_when_still: False: a ``predict`` whose increment is exactly zero (the robot stood still; the motion
            model's noise, proportional to the motion, is zero too) leaves the particles as they are and draws
            nothing from the generator. True (default): it draws the motion noise all the same, scaled by zero,
            and copies the set, as every registered env before ``SemReloc-v21`` did.
    """

    n_particles: int | None = 2000
    lidar_field: LikelihoodFieldConfig = LikelihoodFieldConfig()
    semantic_field: LikelihoodFieldConfig = DEFAULT_SEMANTIC_FIELD
    negative_evidence: NegativeEvidenceConfig = NO_NEGATIVE_EVIDENCE
    motion: OdometryMotionConfig = OdometryMotionConfig()
    belief: BeliefConfig = BeliefConfig()
    use_semantic: bool = True
    likelihood_scale: float = 0.1
    update_min_d_m: float = 0.1
    update_min_a_rad: float = 0.15
    resampler: str = "systematic"
    resample_ess_frac: float = 0.5
    holdoff_min_detections: int = 0
    kld: bool = False
    kld_bin_xy_m: float = 0.5
    kld_bin_theta_rad: float = math.radians(10.0)
    kld_epsilon: float = 0.05
    kld_z: float = 2.326
    kld_one_sequence: bool = False
    min_particles: int = 200
    max_particles: int = 5000
    global_particles_per_m2: float = 0.0
    resample_mode: str = "global"
    cluster_keep_weight: float = 1e-3
    cluster_min_particles: int = 50
    augmented: bool = False
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    injection: str = "uniform"
    proposal_candidates: int = 2000
    proposal_semantic_frac: float = 0.5
    proposal_frac: float = 0.0
    proposal_weight: float = 1.0
    proposal_prior_weight: float = 0.0
    proposal_candidates_per_particle: float = 20.0
    audit_window: int = 0
    audit_margin: float = 1.0
    audit_candidates: int = 2000
    audit_candidates_per_m2: float = 0.0
    audited_convergence: bool = False
    audit_places: int = 0
    audit_screen: bool = False
    audit_screen_pause: int = 100
    audit_screen_pause_place: bool = False
    audit_blur_margin: float = 0.0
    surprise_ratio: float = 0.0
    audit_after_surprise: bool = False
    audit_after_surprise_once: bool = False
    audit_after_lost_hold: bool = False
    hold_init_pose: bool = False
    places_follow_odometry: bool = True
    lost_hold_window: int = 0
    surprise_own_average: bool = False
    semantic_surprise_ratio: float = 0.0
    semantic_surprise_min_beams: int = 3
    semantic_surprise_updates: int = 2
    max_update_log_ratio: float = math.inf
    lidar_on_rotation: bool = True
    backend: str = "numba"
    fast_path: bool = True
    belief_between_updates: str = "exact"
    predict_when_still: bool = True

    def __post_init__(self) -> None:
        for name, cls in _SUBCONFIGS.items():
            v = getattr(self, name)
            if isinstance(v, dict):
                try:
                    object.__setattr__(self, name, cls(**v))
                except TypeError as e:  # unknown key: name the field and the keys it has
                    keys = sorted(f.name for f in fields(cls))
                    raise TypeError(f"MCLConfig.{name}: {e}; its keys are {keys}") from None
            elif not isinstance(v, cls):
                raise TypeError(f"MCLConfig.{name} must be a {cls.__name__} or a dict, got {type(v).__name__}")
        k = self.audit_window
        if not (is_int(k) and 0 <= k <= MAX_AUDIT_WINDOW):
            raise ValueError(f"MCLConfig.audit_window must be an int in [0, {MAX_AUDIT_WINDOW}], got {k!r}")
        object.__setattr__(self, "audit_window", int(k))
        m = self.lost_hold_window
        if not (is_int(m) and 0 <= m <= MAX_AUDIT_WINDOW):
            raise ValueError(f"MCLConfig.lost_hold_window must be an int in [0, {MAX_AUDIT_WINDOW}], got {m!r}")
        object.__setattr__(self, "lost_hold_window", int(m))
        names = ("n_particles", "min_particles", "max_particles", "cluster_min_particles", "proposal_candidates")
        p = self.audit_screen_pause
        if not (is_int(p) and p >= 0):
            raise ValueError(f"MCLConfig.audit_screen_pause must be an int >= 0 (updates), got {p!r}")
        object.__setattr__(self, "audit_screen_pause", int(p))
        if not (is_int(self.audit_places) and 0 <= self.audit_places <= MAX_AUDIT_PLACES):
            raise ValueError(
                f"MCLConfig.audit_places must be an int in [0, {MAX_AUDIT_PLACES}], got {self.audit_places!r}"
            )
        object.__setattr__(self, "audit_places", int(self.audit_places))
        for name in (*names, "audit_candidates"):
            v = getattr(self, name)
            if name == "n_particles" and v is None:
                if not self.global_particles_per_m2 > 0:
                    raise ValueError("MCLConfig: n_particles=None needs global_particles_per_m2 > 0")
                continue
            if not (is_int(v) and 1 <= v <= MAX_PARTICLES):
                raise ValueError(f"MCLConfig.{name} must be an int in [1, {MAX_PARTICLES:,}], got {v!r}")
            object.__setattr__(self, name, int(v))
        if self.min_particles > self.max_particles:
            raise ValueError(
                f"MCLConfig: min_particles ({self.min_particles}) must be <= max_particles ({self.max_particles}); "
                "a default you did not set may be the one in the way (SemReloc envs: min_particles=500): set both"
            )
        h = self.holdoff_min_detections
        if not (is_int(h) and h >= 0):
            raise ValueError(f"MCLConfig.holdoff_min_detections must be an int >= 0, got {h!r}")
        object.__setattr__(self, "holdoff_min_detections", int(h))
        m = self.semantic_surprise_min_beams
        if not (is_int(m) and m >= 1):
            raise ValueError(f"MCLConfig.semantic_surprise_min_beams must be an int >= 1 (labelled beams), got {m!r}")
        object.__setattr__(self, "semantic_surprise_min_beams", int(m))
        k = self.semantic_surprise_updates
        if not (is_int(k) and k >= 1):
            raise ValueError(f"MCLConfig.semantic_surprise_updates must be an int >= 1, got {k!r}")
        object.__setattr__(self, "semantic_surprise_updates", int(k))
        numbers = {  # name: (test, what it must be)
            "update_min_d_m": (lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0"),
            "update_min_a_rad": (lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0"),
            **{
                n: (lambda v: math.isfinite(v) and v > 0, "a finite number > 0")
                for n in ("likelihood_scale", "kld_epsilon", "kld_z")
            },
            # an outside audit's: 1e-300 m or rad bins overflowed the bin indices, and all particles shared one bin
            "kld_bin_xy_m": (lambda v: MIN_KLD_BIN_XY_M <= v < math.inf, f"a finite number >= {MIN_KLD_BIN_XY_M:g} m"),
            "kld_bin_theta_rad": (
                lambda v: MIN_BIN_THETA_RAD <= v < math.inf,
                "a finite number >= MIN_BIN_THETA_RAD = 2 pi / 3600 (0.1 deg)",
            ),
            "resample_ess_frac": (lambda v: 0.0 <= v <= 1.0, "in [0, 1]"),
            "alpha_slow": (lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            "alpha_fast": (lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            **{
                n: (lambda v: 0.0 <= v <= 1.0, "in [0, 1]")
                for n in ("cluster_keep_weight", "proposal_semantic_frac", "proposal_frac", "proposal_prior_weight")
            },
            "proposal_weight": (lambda v: 0.0 < v <= 1.0, "in (0, 1]"),
            "proposal_candidates_per_particle": (lambda v: 1.0 <= v <= MAX_PARTICLES, f"in [1, {MAX_PARTICLES:,}]"),
            "global_particles_per_m2": (lambda v: 0 <= v <= MAX_PARTICLES, f"in [0, {MAX_PARTICLES:,}]"),
            "audit_margin": (lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0"),
            "audit_blur_margin": (lambda v: math.isfinite(v) and v >= 0, "a finite number >= 0 (0 = off)"),
            "audit_candidates_per_m2": (lambda v: 0 <= v <= MAX_PARTICLES, f"in [0, {MAX_PARTICLES:,}]"),
            "surprise_ratio": (lambda v: 0.0 <= v < 1.0, "in [0, 1) (0 = off)"),
            "semantic_surprise_ratio": (lambda v: 0.0 <= v < 1.0, "in [0, 1) (0 = off)"),
            "max_update_log_ratio": (lambda v: v > 0 and not math.isnan(v), "> 0 (inf = no cap)"),
        }
        for name, (ok, what) in numbers.items():
            v = getattr(self, name)
            if not (is_real(v) and ok(float(v))):
                raise ValueError(f"MCLConfig.{name} must be {what}, got {v!r}")
            if isinstance(v, np.generic):  # plain Python numbers: JSON-able, hash as the same value
                object.__setattr__(self, name, v.item())
            elif not isinstance(v, (int, float)):  # a Fraction or Decimal: the arrays it meets would hold objects
                object.__setattr__(self, name, float(v))
        if not isinstance(self.resampler, str):
            raise ValueError(f"MCLConfig.resampler must be a name (str), got {self.resampler!r:.60}")
        if self.resampler not in RESAMPLERS:
            get_resampler(self.resampler)  # raises with the list of names
        if self.resample_mode not in ("global", "clustered"):
            raise ValueError(f"MCLConfig.resample_mode must be 'global' or 'clustered', got {self.resample_mode!r}")
        if self.injection not in ("uniform", "scan"):
            raise ValueError(f"MCLConfig.injection must be 'uniform' or 'scan', got {self.injection!r}")
        for name in (
            "use_semantic", "kld", "augmented", "lidar_on_rotation", "fast_path", "audited_convergence", "audit_screen",
            "audit_screen_pause_place", "audit_after_surprise", "audit_after_surprise_once", "audit_after_lost_hold",
            "hold_init_pose", "surprise_own_average", "places_follow_odometry", "predict_when_still",
            "kld_one_sequence",
        ):  # fmt: skip
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise ValueError(f"MCLConfig.{name} must be a bool, got {getattr(self, name)!r}")
        if self.backend not in ("numba", "numpy"):
            raise ValueError(f"MCLConfig.backend must be 'numba' or 'numpy', got {self.backend!r}")
        if self.belief_between_updates not in BELIEF_BETWEEN_UPDATES:
            raise ValueError(
                f"MCLConfig.belief_between_updates must be one of {BELIEF_BETWEEN_UPDATES}, "
                f"got {self.belief_between_updates!r:.60}"
            )
        needs = {}  # option: (its "off" value, why it cannot stay on); all in one message
        if self.audit_after_surprise and not (self.surprise_ratio > 0 and self.audit_window > 0):
            needs["audit_after_surprise"] = (
                False,
                "MCLConfig.audit_after_surprise needs the surprise test and the audit (surprise_ratio > 0 and "
                f"audit_window > 0), got surprise_ratio={self.surprise_ratio}, audit_window={self.audit_window}",
            )
        if self.audit_after_surprise_once and (not self.audit_after_surprise or "audit_after_surprise" in needs):
            needs["audit_after_surprise_once"] = (
                False,
                "MCLConfig.audit_after_surprise_once needs audit_after_surprise=True (and what that needs), got "
                f"audit_after_surprise={self.audit_after_surprise}",
            )
        if self.audit_after_lost_hold and not (self.audit_window > 0 and self.belief.converged_hold_weight is not None):
            needs["audit_after_lost_hold"] = (
                False,
                "MCLConfig.audit_after_lost_hold needs the audit and a held convergence (audit_window > 0 and "
                f"belief.converged_hold_weight set), got audit_window={self.audit_window}, "
                f"belief.converged_hold_weight={self.belief.converged_hold_weight}",
            )
        if self.hold_init_pose and self.belief.converged_hold_weight is None:
            needs["hold_init_pose"] = (
                False,
                "MCLConfig.hold_init_pose needs a held convergence (belief.converged_hold_weight set), got "
                f"belief.converged_hold_weight={self.belief.converged_hold_weight}",
            )
        if self.lost_hold_window and not (
            self.audit_after_lost_hold and self.audited_convergence and self.lost_hold_window <= self.audit_window
        ):
            needs["lost_hold_window"] = (
                0,
                "MCLConfig.lost_hold_window needs audit_after_lost_hold=True and audited_convergence=True (and what "
                "those need), and at most audit_window scans (the window holds no more: a larger wait would never "
                f"end), got audit_after_lost_hold={self.audit_after_lost_hold}, "
                f"audited_convergence={self.audited_convergence}, lost_hold_window={self.lost_hold_window}, "
                f"audit_window={self.audit_window}",
            )
        if self.surprise_own_average and not self.surprise_ratio > 0:
            needs["surprise_own_average"] = (
                False,
                "MCLConfig.surprise_own_average needs the surprise test (surprise_ratio > 0), got "
                f"surprise_ratio={self.surprise_ratio}",
            )
        if self.semantic_surprise_ratio > 0 and not (self.surprise_ratio > 0 and self.surprise_own_average):
            needs["semantic_surprise_ratio"] = (
                0.0,
                "MCLConfig.semantic_surprise_ratio needs the surprise test with its own average (surprise_ratio > 0 "
                f"and surprise_own_average=True), got surprise_ratio={self.surprise_ratio}, "
                f"surprise_own_average={self.surprise_own_average}",
            )
        if self.audit_blur_margin > 0 and not (self.audit_screen and self.audit_window > 0):
            needs["audit_blur_margin"] = (
                0.0,
                "MCLConfig.audit_blur_margin needs the audit's screen (audit_screen=True and audit_window > 0), "
                f"got audit_screen={self.audit_screen}, audit_window={self.audit_window}",
            )
        if needs:
            hint = {name: off for name, (off, _) in needs.items()}
            raise ValueError("; ".join(why for _, why in needs.values()) + f" (to turn those off too, also set {hint})")

    def as_dict(self) -> dict:
        """Nested plain dict (sub-configs as dicts); ``MCLConfig(**cfg.as_dict())`` round-trips."""
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = {g.name: getattr(v, g.name) for g in fields(v)} if f.name in _SUBCONFIGS else v
        return out


def check_overrides(overrides: dict, what: str, base: MCLConfig | None = None) -> None:
    """Raise ``ValueError`` naming ``what`` (a command's option) if ``overrides`` are not valid
    `MCLConfig` fields and values on top of ``base`` (an env's default relocalizer, whose other fields an
    override may depend on; default `MCLConfig()`); a dict for a sub-config overrides the fields it names.
    Commands call it before any episode runs."""
    names = {f.name for f in fields(MCLConfig)}
    unknown = sorted(set(overrides) - names, key=str)
    if unknown:
        raise ValueError(f"{what}: unknown keys {unknown}; valid keys: {sorted(names)}")
    try:
        if base is None:
            MCLConfig(**overrides)
        else:
            merged = {
                k: {**asdict(getattr(base, k)), **v} if k in _SUBCONFIGS and isinstance(v, dict) else v
                for k, v in overrides.items()
            }
            replace(base, **merged)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{what}: {e}") from None


@dataclass(frozen=True)
class UpdateDiagnostics:
    """What one `MonteCarloLocalizer.update` did.

    Attributes:
        updated: the measurement update ran (False: skipped by the motion gate).
        n_lidar_beams, n_semantic_beams: beams used (semantic: labelled beams only).
        n_detections: objects in this semantic scan; ``detections_seen`` since the last init.
        mean_lidar_beam_likelihood: ``mean_i exp(lidar_ll_i / n_lidar_beams)`` over the
            particles *before* resampling — the per-beam "mean particle weight (lidar
            factor)" that paper 004 plots against iteration (NaN if no lidar beam).
        ess: effective sample size after weighting, before resampling.
        resampled: particles were resampled.
        holdoff_active: resampling was wanted (ESS low) but held off.
        n_particles: particle count after this update (changes with KLD).
        n_injected: random particles injected (augmented MCL).
        recovered: all weights underflowed and the filter was re-initialised globally.
        w_slow, w_fast: augmented-MCL averages after this update.
        p_inject: the injection probability ``max(0, 1 - w_fast / w_slow)`` of this update.
        lidar_used: the lidar factor was part of this update.
        n_negative_beams: unlabelled camera beams sampled for negative evidence
            (`NegativeEvidenceConfig`, at most its ``max_beams``; 0 when it is off).
        audit_log_ratio: the convergence audit's best alternative's window log-likelihood minus the
            converged hypothesis's (tempered nats; NaN when no audit ran: ``audit_window`` 0, after
            ``init_around``, the set did not just become converged, an audit cleared the same place
            fewer than ``audit_window`` updates before, or nothing lay outside the hypothesis).
        n_audit_injected: particles the audit added around that alternative (0 or
            ``cluster_min_particles``).
        surprise: this update was a surprise (`MCLConfig.surprise_ratio`, or the semantic test's).
        semantic_surprise: the semantic surprise test found this update surprising
            (`MCLConfig.semantic_surprise_ratio`; ``surprise`` is then True too).
        w_surprise: the surprise test's own average after this update (`MCLConfig.surprise_own_average`; 0
            when it is off).
        w_semantic: this update's average semantic likelihood per labelled beam, as the semantic surprise
            test judged it (NaN when it did not: the test is off, or too few labelled beams).
    """

    updated: bool = False
    n_lidar_beams: int = 0
    n_semantic_beams: int = 0
    n_detections: int = 0
    detections_seen: int = 0
    mean_lidar_beam_likelihood: float = float("nan")
    ess: float = float("nan")
    resampled: bool = False
    holdoff_active: bool = False
    n_particles: int = 0
    n_injected: int = 0
    recovered: bool = False
    w_slow: float = 0.0
    w_fast: float = 0.0
    p_inject: float = 0.0
    lidar_used: bool = False
    n_negative_beams: int = 0
    audit_log_ratio: float = float("nan")
    n_audit_injected: int = 0
    surprise: bool = False
    semantic_surprise: bool = False
    w_surprise: float = 0.0
    w_semantic: float = float("nan")

    def as_dict(self) -> dict:
        """Plain Python values for a Gymnasium ``info``."""
        names = _FIELD_NAMES.get(type(self))
        if names is None:  # once per class: dataclasses.fields is slow for a call per step
            names = _FIELD_NAMES[type(self)] = tuple(f.name for f in fields(self))
        return {name: getattr(self, name) for name in names}


_FIELD_NAMES: dict[type, tuple[str, ...]] = {}


def _beam_average(prior: np.ndarray, ll: np.ndarray, n_beams: int) -> float:
    """``sum_i prior_i * exp(ll_i / n_beams)``: the particles' average likelihood per beam (0 where ``ll`` is not
    finite), summed in one order whatever the BLAS thread count."""
    fin = np.isfinite(ll)
    return float(_blas.dot(prior, np.where(fin, np.exp(np.where(fin, ll, 0.0) / n_beams), 0.0)))


def _holds_bool(value) -> bool:
    """Whether ``value`` is or holds a bool (a bool is never a number here: `filters.numbers`)."""
    return any(isinstance(v, (bool, np.bool_)) for v in np.asarray(value, dtype=object).reshape(-1))


class MonteCarloLocalizer:
    """Monte Carlo localization with a lidar x semantic likelihood field (paper 004).

    Args:
        grid: the map (occupancy + semantic grids).
        config: an `MCLConfig` (or a dict of its fields); None = defaults.
        rng: the ``numpy.random.Generator`` every random draw comes from.
        measurement_model: optional object with ``log_likelihood_terms(poses, lidar, semantic)
            -> (lidar_ll, semantic_ll, beams)`` replacing the likelihood-field model (for tests
            and experiments; ``beams`` carries the counts ``n_lidar``, ``n_semantic`` and
            ``n_detections``, as `filters.localization.likelihood_field.BeamSet` does); None =
            `LikelihoodFieldModel` from the config.

    The particle set is empty until `init_global` or `init_around`;
    `predict` and `update` raise ``ValueError`` on an empty set.
    """

    def __init__(
        self,
        grid: GridMap,
        config: MCLConfig | dict | None = None,
        rng: np.random.Generator | None = None,
        measurement_model=None,
    ) -> None:
        if not isinstance(grid, GridMap):
            raise TypeError(f"grid must be a filters.mapping.grid.GridMap, got {type(grid).__name__}")
        if isinstance(config, dict):
            config = MCLConfig(**config)
        self.config: MCLConfig = config if config is not None else MCLConfig()
        if not isinstance(self.config, MCLConfig):
            raise TypeError(f"config must be an MCLConfig or a dict, got {type(config).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise TypeError("rng must be a numpy.random.Generator (no hidden global randomness)")
        if grid.free_cells().size == 0:  # an outside audit's: update failed later, after changing the filter
            raise ValueError(
                f"the map has no free cell (occupancy < free_thresh {grid.free_thresh:g}): the filter draws particles "
                "over free space (a global start, injections, recovery, the audit); check the map's thresholds and "
                "how it stores free space"
            )
        self.grid = grid
        self.rng = rng
        c = self.config
        self.motion_model = OdometryMotionModel(c.motion)
        self.measurement_model = (
            measurement_model
            if measurement_model is not None
            else LikelihoodFieldModel(grid, c.lidar_field, c.semantic_field, c.backend, c.negative_evidence)
        )
        if c.audit_screen and c.audit_window > 0 and not isinstance(self.measurement_model, LikelihoodFieldModel):
            raise TypeError(
                "MCLConfig.audit_screen needs a LikelihoodFieldModel as the measurement model (it screens the "
                f"map with blurred copies of its fields), got {type(self.measurement_model).__name__}; "
                "set audit_screen=False (or audit_window=0) for another model"
            )
        self._resample = get_resampler(c.resampler)
        self._belief_backend = "numba" if c.fast_path else "numpy"
        self._lse = fast_logsumexp if c.fast_path else logsumexp  # the same bits (filters.smc.logsumexp)
        self._proposal: ScanProposal | None = None
        self._poses = np.zeros((0, 3))
        self._logw = np.zeros(0)
        self._budget = 0  # size of the last set given (`_set`): what a resampling without KLD draws
        self._summary_cache: tuple[np.ndarray, np.ndarray, Belief] | None = None
        self._anchor: tuple[np.ndarray, np.ndarray] | None = None
        """``(poses, log-weights)``: the set the last update or init left (``belief_between_updates``)."""
        self._reset_state()
        self.last_diagnostics = UpdateDiagnostics()

    # ------------------------------------------------------------ state
    def _reset_state(self) -> None:
        self._since_update = np.zeros(3)
        self._since_lidar_m = 0.0
        self._has_updated = False
        self._detections_seen = 0
        self._w_slow = 0.0
        self._w_fast = 0.0
        self._w_surprise = 0.0  # the surprise test's own average (`MCLConfig.surprise_own_average`)
        self._w_sem_surprise = 0.0  # the semantic surprise test's average (`MCLConfig.semantic_surprise_ratio`)
        self._sem_low_run = 0  # consecutive updates the semantic surprise test found low
        self.n_updates = 0
        """Measurement updates that ran since the last init."""
        self._window: audit.Window = []
        """The last ``audit_window`` updates' scans and odometry (`filters.localization.audit.Window`)."""
        self._window_met: list[bool] = []
        """Per `_window` entry, whether the set met the "converged" criterion by itself after that update
        (`MCLConfig.lost_hold_window`)."""
        self._window_least = 0  # scans the window must hold before the audit judges (`MCLConfig.lost_hold_window`)
        self._was_converged = False
        self._cleared: tuple[np.ndarray, int] | None = None  # (mean, n_updates) of the last hypothesis an audit cleared
        # (n_updates, hypothesis mean carried along the odometry since) of the last audit whose screen found nothing
        self._screen_cleared: tuple[int, np.ndarray] | None = None
        self._audit_on = False  # the convergence audit runs after init_global (or a surprise: audit_after_surprise)
        self._audit_by_surprise = False  # a surprise turned the audit on (`MCLConfig.audit_after_surprise_once`)
        self.converged_updates = 0
        """Consecutive measurement updates, the latest included, after which the set met the
        "converged" criterion (counted only when ``belief.converged_min_updates > 1``)."""
        self._held: np.ndarray | None = None
        """Mean of the hypothesis called converged after the last update (``belief.converged_hold_weight``)."""
        self._ever_converged = False  # some update since the init was converged (`MCLConfig.surprise_ratio`)

    @property
    def poses(self) -> np.ndarray:
        """``(N, 3)`` particle poses (read-only view), ``(x m, y m, theta rad)``."""
        v = self._poses.view()
        v.setflags(write=False)
        return v

    @property
    def log_weights(self) -> np.ndarray:
        """``(N,)`` normalised log-weights (log-sum-exp = 0), read-only view."""
        v = self._logw.view()
        v.setflags(write=False)
        return v

    @property
    def weights(self) -> np.ndarray:
        """``(N,)`` normalised weights (sum 1), a new array."""
        return np.exp(self._logw)

    @property
    def n_particles(self) -> int:
        return int(self._poses.shape[0])

    # ------------------------------------------------------------ init
    def _free_cell_index(self) -> np.ndarray:
        cells = self.grid.free_cells()
        if cells.size == 0:
            raise ValueError("the map has no free cell (occupancy < free_thresh): cannot spread particles")
        return cells

    def sample_free(self, n: int) -> np.ndarray:
        """``(n, 3)`` poses uniform over free space (uniform cell, uniform inside it) and heading."""
        cells = self._free_cell_index()
        k = cells[self.rng.integers(0, cells.size, size=n)]
        row, col = np.divmod(k, self.grid.shape[1])
        u = self.rng.random((n, 3))
        ox, oy = self.grid.origin_xy_m
        res = self.grid.resolution_m
        out = np.empty((n, 3))
        out[:, 0] = ox + (col + u[:, 0]) * res
        out[:, 1] = oy + (row + u[:, 1]) * res
        out[:, 2] = wrap_angle(-np.pi + 2.0 * np.pi * u[:, 2])
        return out

    @staticmethod
    def _check_n(n: int) -> int:
        if not is_int(n):
            raise TypeError(f"particle count must be an int, got {n!r}")
        if not 1 <= n <= MAX_PARTICLES:
            raise ValueError(f"particle count must be in [1, {MAX_PARTICLES:,}], got {n}")
        return int(n)

    def _set(self, poses: np.ndarray) -> None:
        """A new particle set of equal weights; its size is what a resampling without KLD draws."""
        self._poses = np.ascontiguousarray(poses, dtype=np.float64)
        self._logw = np.full(self._poses.shape[0], -math.log(self._poses.shape[0]))
        self._budget = self._poses.shape[0]
        self._anchor = (self._poses, self._logw)

    @property
    def free_area_m2(self) -> float:
        """Free area of the map, m^2 (cells below the free threshold)."""
        return float(self._free_cell_index().size * self.grid.resolution_m**2)

    def global_particle_count(self) -> int:
        """The particle count ``init_global`` draws by default (see the module docstring)."""
        c = self.config
        if c.n_particles is not None:
            return c.n_particles
        n = round(c.global_particles_per_m2 * self.free_area_m2)
        return int(min(max(n, c.min_particles), c.max_particles))

    def init_global(self, n: int | None = None) -> None:
        """Spread ``n`` particles uniformly over free space (default `global_particle_count`).

        Raises:
            ValueError: ``n < 1`` or the map has no free cell.
        """
        n = self._check_n(self.global_particle_count() if n is None else n)
        self._set(self.sample_free(n))
        self._reset_state()
        self._audit_on = True

    def init_around(self, pose, std, n: int | None = None) -> None:
        """Gaussian cloud of ``n`` particles around ``pose (x, y, theta)`` (default: module docstring).

        Args:
            pose: ``(3,)`` centre, metres / radians, within the map's extent (``GridMap.extent_m``).
            std: scalar or ``(3,)`` standard deviations ``(x m, y m, theta rad)``, >= 0.

        With ``MCLConfig.hold_init_pose`` the belief holds ``pose`` as converged from here on (until the hold is
        lost) and the surprise tests are armed.

        Raises:
            ValueError: a pose that is not 3 finite numbers or lies outside the map; a bad ``std``
                or ``n``. The filter is left as it was.
        """
        if n is None:
            n = self.config.n_particles if self.config.n_particles is not None else self.config.min_particles
        n = self._check_n(n)
        try:
            p = np.asarray(pose, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            p = None
        if p is None or p.shape != (3,) or not np.all(np.isfinite(p)) or _holds_bool(pose):
            raise ValueError(f"pose must be 3 finite numbers, got {pose!r:.80}")
        x0, x1, y0, y1 = self.grid.extent_m
        if not (x0 <= p[0] <= x1 and y0 <= p[1] <= y1):
            raise ValueError(
                f"pose ({p[0]:.6g}, {p[1]:.6g}) lies outside the map, x in [{x0:.6g}, {x1:.6g}] m and "
                f"y in [{y0:.6g}, {y1:.6g}] m (a pose in the map's frame was meant?)"
            )
        try:
            s = np.broadcast_to(np.asarray(std, dtype=np.float64), (3,))
        except (TypeError, ValueError):
            s = None
        if s is None or not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s > MAX_LENGTH_M) or _holds_bool(std):
            raise ValueError(f"std must be a number or 3 numbers in [0, {MAX_LENGTH_M:g}], got {std!r:.80}")
        rng_state = self.rng.bit_generator.state
        with np.errstate(over="ignore", invalid="ignore"):
            poses = p + self.rng.standard_normal((n, 3)) * s
        if not np.all(np.isfinite(poses)):  # a huge std (1e308): keep the filter as it was
            self.rng.bit_generator.state = rng_state
            raise ValueError(f"std {std!r:.80} spreads the particles to non-finite poses")
        poses[:, 2] = wrap_angle(poses[:, 2])
        self._set(poses)
        self._reset_state()
        if self.config.hold_init_pose:
            self._held = np.array([p[0], p[1], wrap_angle(p[2])])
            self._ever_converged = True

    def _require_particles(self) -> None:
        if self._poses.shape[0] == 0:
            raise ValueError("no particles: call init_global() or init_around() first")

    # ------------------------------------------------------------ filter steps
    def predict(self, delta) -> None:
        """Move every particle by a noisy copy of the odometry increment ``delta = (dx, dy, dtheta)``
        (metres / radians, previous robot frame, as `filters.pose.relative` gives)."""
        self._require_particles()
        d = np.array(finite_increment(delta, "odometry delta"))
        if self.config.predict_when_still or d.any():
            rng_state = self.rng.bit_generator.state
            poses = self.motion_model.sample(self._poses, d, self.rng)
            if not np.isfinite(poses).all():  # e.g. a delta of 1e300 m: keep the filter as it was
                self.rng.bit_generator.state = rng_state
                raise ValueError(f"odometry delta {delta!r} moves particles to non-finite poses")
            self._poses = poses
        self._since_update = compose(self._since_update, d)
        if self._screen_cleared is not None:
            self._screen_cleared = (self._screen_cleared[0], compose(self._screen_cleared[1], d))
        if self.config.places_follow_odometry:
            if self._held is not None:
                self._held = compose(self._held, d)
            if self._cleared is not None:
                self._cleared = (compose(self._cleared[0], d), self._cleared[1])

    def moved_enough(self) -> bool:
        """Whether the motion since the last update passes the ``update_min_*`` gate."""
        c = self.config
        if c.update_min_d_m == 0 and c.update_min_a_rad == 0:
            return True
        d = math.hypot(self._since_update[0], self._since_update[1])
        a = abs(float(self._since_update[2]))
        return d > c.update_min_d_m or a > c.update_min_a_rad

    def update(
        self, lidar: LaserScan | None, semantic: SemanticScan | None = None, force: bool = False
    ) -> UpdateDiagnostics:
        """Weight by the scans, maybe resample; returns (and stores in ``last_diagnostics``) what it did.

        Args:
            lidar: the lidar scan (None: semantic factor only).
            semantic: the semantic pseudo-laser scan, or None (ignored if ``use_semantic`` is False).
            force: run even if the robot has not moved enough since the last update.
        """
        self._require_particles()
        if lidar is not None and not isinstance(lidar, LaserScan):
            raise TypeError(f"lidar must be a LaserScan, got {type(lidar).__name__}")
        if semantic is not None and not isinstance(semantic, SemanticScan):
            raise TypeError(f"semantic must be a SemanticScan, got {type(semantic).__name__}")
        if not isinstance(force, (bool, np.bool_)):
            raise TypeError(f"force must be a bool, got {force!r}")
        c = self.config
        check_labels = getattr(self.measurement_model, "check_labels", None)
        if semantic is not None and c.use_semantic and check_labels is not None:
            check_labels(semantic)  # refused whether or not the motion gate lets this update run
        n = self.n_particles
        if self._has_updated and not force and not self.moved_enough():
            diag = UpdateDiagnostics(
                updated=False,
                detections_seen=self._detections_seen,
                n_particles=n,
                w_slow=self._w_slow,
                w_fast=self._w_fast,
                w_surprise=self._w_surprise,
            )
            self.last_diagnostics = diag
            return diag

        sem = semantic if c.use_semantic else None
        moved_m = math.hypot(self._since_update[0], self._since_update[1])
        use_lidar = lidar is not None and (
            c.lidar_on_rotation or not self._has_updated or force or self._since_lidar_m + moved_m > c.update_min_d_m
        )
        lid = lidar if use_lidar else None
        ll_l, ll_s, beams = self.measurement_model.log_likelihood_terms(self._poses, lid, sem)
        ll_l = np.asarray(ll_l, dtype=np.float64)
        ll_s = np.asarray(ll_s, dtype=np.float64)
        for what, a in (("lidar", ll_l), ("semantic", ll_s)):  # broadcasting would make (N, N) log-weights
            if a.shape not in ((n,), ()):
                raise ValueError(
                    f"the measurement model's {what} log-likelihoods must have shape ({n},) or be one number, got "
                    f"shape {a.shape}"
                )
        ll = ll_l + ll_s
        ll = np.where(np.isfinite(ll), ll, -np.inf)
        n_beams = beams.n_lidar + beams.n_semantic
        if beams.n_lidar and np.all(np.isfinite(ll_l)):
            mean_lidar = float(np.mean(np.exp(ll_l / beams.n_lidar)))
        else:
            mean_lidar = float("nan")

        delta = self._since_update
        self._since_update = np.zeros(3)
        self._since_lidar_m = 0.0 if use_lidar else self._since_lidar_m + moved_m
        self._has_updated = True
        self.n_updates += 1
        self._detections_seen += int(beams.n_detections)

        tempered = c.likelihood_scale * ll
        if math.isfinite(c.max_update_log_ratio) and np.isfinite(tempered).any():
            # the cap lifts the unlikely, not what the model rules out (-inf stays -inf)
            floor = np.max(tempered) - c.max_update_log_ratio
            tempered = np.where(np.isfinite(tempered), np.maximum(tempered, floor), -np.inf)
        predicted = (self._poses, self._logw)  # the belief before this update (routine proposals' prior)
        logw = self._logw + tempered
        finite_any = bool(np.any(np.isfinite(logw)))
        lse = float(self._lse(logw)) if finite_any else -np.inf
        if not math.isfinite(lse):
            self.init_global(n)
            diag = UpdateDiagnostics(
                updated=True,
                n_lidar_beams=beams.n_lidar,
                n_semantic_beams=beams.n_semantic,
                n_detections=beams.n_detections,
                mean_lidar_beam_likelihood=mean_lidar,
                n_particles=self.n_particles,
                recovered=True,
                lidar_used=use_lidar,
                n_negative_beams=getattr(beams, "n_negative", 0),
            )
            self.last_diagnostics = diag
            return diag

        p_inj = 0.0
        surprise = semantic_surprise = False
        w_sem = math.nan
        held_before = self._held is not None  # a held convergence from the last update (audit_after_lost_hold)
        if beams.n_semantic < c.semantic_surprise_min_beams:
            self._sem_low_run = 0  # not judged: breaks the semantic test's run (a beamless update too)
        if (c.augmented or c.surprise_ratio > 0.0) and n_beams:
            prior = np.exp(self._logw)
            w_avg = _beam_average(prior, ll, n_beams)
            # judged on updates that used the lidar only: a turn-in-place update's few camera beams
            # average too noisily to compare with the averages the lidar's updates made
            ref = self._w_surprise if c.surprise_own_average else self._w_fast
            surprise = self._ever_converged and beams.n_lidar > 0 and ref > 0.0 and w_avg < c.surprise_ratio * ref
            if c.semantic_surprise_ratio > 0.0 and beams.n_semantic >= c.semantic_surprise_min_beams:
                w_sem = _beam_average(prior, ll_s, beams.n_semantic)
                ref_s = self._w_sem_surprise
                low = self._ever_converged and ref_s > 0.0 and w_sem < c.semantic_surprise_ratio * ref_s
                self._sem_low_run = self._sem_low_run + 1 if low else 0
                semantic_surprise = self._sem_low_run >= c.semantic_surprise_updates
            surprise = surprise or semantic_surprise
            if c.surprise_own_average:
                # as w_fast, but restarted at a surprise (the level after the jump is the new normal) and never
                # by an injection
                fresh = surprise or self._w_surprise == 0.0
                self._w_surprise = w_avg if fresh else self._w_surprise + c.alpha_fast * (w_avg - self._w_surprise)
                if surprise:
                    self._w_sem_surprise, self._sem_low_run = 0.0, 0
                if math.isfinite(w_sem):
                    a = self._w_sem_surprise
                    self._w_sem_surprise = w_sem if a == 0.0 else a + c.alpha_fast * (w_sem - a)
            if surprise:
                self._held, self._window, self._cleared, self._was_converged = None, [], None, False
                self._window_met, self._window_least = [], 0
                self._screen_cleared = None
                if c.audit_after_surprise and not self._audit_on:
                    self._audit_on = self._audit_by_surprise = True
            if self._w_slow == 0.0:  # pf.c: the averages start at the first average
                self._w_slow = self._w_fast = w_avg
            else:
                self._w_slow += c.alpha_slow * (w_avg - self._w_slow)
                self._w_fast += c.alpha_fast * (w_avg - self._w_fast)
            if c.augmented and self._w_slow > 0.0:
                p_inj = max(0.0, 1.0 - self._w_fast / self._w_slow)

        self._logw = logw - lse
        w = np.exp(self._logw)
        ess = float(1.0 / np.sum(w * w))
        want = ess < c.resample_ess_frac * n
        held = c.use_semantic and c.holdoff_min_detections > 0 and self._detections_seen < c.holdoff_min_detections
        resampled = False
        if want and not held:
            self._resample_now(w)
            resampled = True
        p_any = max(p_inj, c.proposal_frac)
        # proposals are weighted by the whole current scan, also when the lidar factor sat this update out
        n_inj = self._inject(p_any, lidar, sem, recovery=p_inj > c.proposal_frac, prior=predicted) if p_any > 0.0 else 0
        if p_inj > 0.0 and n_inj:
            self._w_slow = self._w_fast = 0.0  # pf.c: restart both averages after a recovery injection
        audit_ratio, n_audit = math.nan, 0
        if c.audit_window and (self._audit_on or c.audit_after_lost_hold):
            # kept while the audit is off too when a lost hold may turn it on: it then judges a full window
            self._window = [*self._window, (lid, sem, delta, beams)][-c.audit_window :]
            if c.lost_hold_window:
                self._window_met = [*self._window_met, self._summary().converged][-c.audit_window :]
        if c.audit_window and self._audit_on:
            audit_ratio, n_audit = self._audit(lidar, sem)
            if n_audit:
                self._held = None  # the audit's doubt ends a held convergence, whatever the weights say
        diag = UpdateDiagnostics(
            updated=True,
            n_lidar_beams=beams.n_lidar,
            n_semantic_beams=beams.n_semantic,
            n_detections=beams.n_detections,
            detections_seen=self._detections_seen,
            mean_lidar_beam_likelihood=mean_lidar,
            ess=ess,
            resampled=resampled,
            holdoff_active=bool(want and held),
            n_particles=self.n_particles,
            n_injected=n_inj,
            recovered=False,
            w_slow=self._w_slow,
            w_fast=self._w_fast,
            p_inject=p_inj,
            lidar_used=use_lidar,
            n_negative_beams=getattr(beams, "n_negative", 0),
            audit_log_ratio=audit_ratio,
            n_audit_injected=n_audit,
            surprise=surprise,
            semantic_surprise=semantic_surprise,
            w_surprise=self._w_surprise,
            w_semantic=w_sem,
        )
        self.last_diagnostics = diag
        self._anchor = (self._poses, self._logw)
        if c.belief.converged_min_updates > 1:
            met = self._summary().converged
            self.converged_updates = self.converged_updates + 1 if met else 0
        if c.belief.converged_hold_weight is not None or c.surprise_ratio > 0.0:
            b = self.belief()
            if c.belief.converged_hold_weight is not None:
                self._held = b.hypotheses[0].mean.copy() if b.converged else None
            if c.audit_after_lost_hold and held_before and not b.converged and not surprise and not self._audit_on:
                # lost without a surprise (which has its own option): the next convergence is a relocalization,
                # judged on the window's scans (a fading hold gives no reason to drop the earlier ones)
                self._audit_on = self._audit_by_surprise = True
                self._cleared, self._screen_cleared, self._was_converged = None, None, False
                if c.lost_hold_window:
                    # the scans up to the last update whose set met the criterion by itself fit the held place:
                    # from before an unnoticed kidnapping, they would testify for it (and its odometry track)
                    met = [i for i, m in enumerate(self._window_met) if m]
                    start = met[-1] + 1 if met else 0
                    self._window, self._window_met = self._window[start:], self._window_met[start:]
                    self._window_least = c.lost_hold_window
            self._ever_converged = self._ever_converged or b.converged
        return diag

    # ------------------------------------------------------------ resampling
    def kld_required(self, k: np.ndarray) -> np.ndarray:
        """Fox's bound ``n_chi(k)`` (float array) for ``k`` occupied bins."""
        return _fox_bound(k, self.config.kld_epsilon, self.config.kld_z)

    @property
    def kld_bounds(self) -> tuple[int, int]:
        """``(min, max)`` particle count of KLD sampling: ``[min_particles, max_particles]``, or
        ``[min(min_particles, n_particles), n_particles]`` when ``n_particles`` is given."""
        c = self.config
        hi = c.max_particles if c.n_particles is None else c.n_particles
        return min(c.min_particles, hi), hi

    def _kld_indices(self, w: np.ndarray) -> np.ndarray:
        lo, hi = self.kld_bounds
        m = min(hi, max(2 * w.size, 4 * lo))  # enough draws almost always
        u = self.rng.random(m)
        idx = self._kld_draw(w, u, lo)
        if idx.size == m and m < hi:  # the bound was not met within m draws
            if self.config.kld_one_sequence:  # Fox's: the same sequence goes on, up to hi
                idx = self._kld_draw(w, np.concatenate([u, self.rng.random(hi - m)]), lo)
            else:  # a sequence of hi draws from scratch
                idx = self._kld_draw(w, self.rng.random(hi), lo)
        return idx

    def _kld_bound_table(self, k_max: int) -> np.ndarray:
        """``kld_required(k)`` for ``k = 0 .. k_max`` at least (one table per process and bound)."""
        _, hi = self.kld_bounds
        return _fox_bound_table(self.config.kld_epsilon, self.config.kld_z, max(k_max, hi) + 1)

    def _kld_draw(self, w: np.ndarray, u: np.ndarray, lo: int) -> np.ndarray:
        """The indices KLD sampling draws with the uniforms ``u`` (one per draw, in order): the first ``n`` of them,
        ``n`` the first count that meets Fox's bound and ``lo`` (all of them if none does)."""
        c = self.config
        m = u.size
        if c.fast_path:
            extent = kld_kernels.dense_extent(self._poses, c.kld_bin_xy_m, c.kld_bin_theta_rad, _MAX_DENSE_KEYS)
            if extent is not None:
                idx = np.empty(m, dtype=np.int64)
                n_new = kld_kernels.kld_draw(
                    self._poses, closed_cdf(w), u, lo, self._kld_bound_table(m),
                    c.kld_bin_xy_m, c.kld_bin_theta_rad, extent, idx,
                )  # fmt: skip
                return idx[:n_new]
        idx = inverse_cdf(w, u)
        p = self._poses[idx]
        keys = linear_bin_keys(
            np.floor(p[:, 0] / c.kld_bin_xy_m).astype(np.int64),
            np.floor(p[:, 1] / c.kld_bin_xy_m).astype(np.int64),
            np.floor((p[:, 2] + np.pi) / c.kld_bin_theta_rad).astype(np.int64),
        )
        _, first = np.unique(keys, return_index=True)
        new_bin = np.zeros(m, dtype=bool)
        new_bin[first] = True
        k = np.cumsum(new_bin)  # occupied bins after 1..m draws
        count = np.arange(1, m + 1)
        ok = (count >= self.kld_required(k)) & (count >= lo)
        n_new = int(np.argmax(ok)) + 1 if ok.any() else m
        return idx[:n_new]

    def _resample_now(self, w: np.ndarray) -> None:
        c = self.config
        if c.resample_mode == "clustered":
            # without KLD the budget is the count drawn at init, not the current count, which the
            # cluster floors below can have raised (it would compound, resampling after resampling)
            n_new = self._kld_indices(w).size if c.kld else self._budget
            poses, logw = self._clustered(w, n_new)
            self._poses = poses
            self._logw = logw
            return
        # without KLD the budget, as above: an audit's added particles must not become the next count
        idx = self._kld_indices(w) if c.kld else self._resample_n(w, self._budget)
        self._set(self._poses[idx])

    def _clustered(self, w: np.ndarray, n_new: int) -> tuple[np.ndarray, np.ndarray]:
        """Within-cluster resampling to about ``n_new`` particles; cluster weights are kept."""
        c = self.config
        b = c.belief
        labels, n_lab = cluster_labels(
            self._poses, b.cluster_bin_m, b.cluster_bin_theta_rad, w, b.cluster_min_bin_frac, self._belief_backend
        )
        labels = np.where(labels < 0, n_lab, labels)  # the haze outside every cluster is one more group
        n_lab += 1
        cw = np.bincount(labels, weights=w, minlength=n_lab)
        keep = np.flatnonzero((cw >= c.cluster_keep_weight) & (cw > 0))  # an empty group has nothing to draw
        if keep.size == 0:
            keep = np.array([int(np.argmax(cw))])
        order, starts = belief_kernels.cluster_members(labels, n_lab)
        total = cw[keep].sum()
        floor = min(c.cluster_min_particles, max(1, n_new // keep.size))  # floors never exceed the budget
        poses, logw = [], []
        for k in keep:
            members = order[starts[k] : starts[k + 1]]
            m = max(floor, round(n_new * cw[k] / total))
            idx = members[self._resample_n(w[members] / cw[k], m)]
            poses.append(self._poses[idx])
            logw.append(np.full(m, math.log(cw[k] / total / m)))
        logw = np.concatenate(logw)
        return np.ascontiguousarray(np.vstack(poses)), logw - self._lse(logw)

    def _resample_n(self, w: np.ndarray, m: int) -> np.ndarray:
        """``m`` indices into ``w`` (normalised): the configured scheme when ``m == len(w)``, else
        systematic pointers (``m`` of them)."""
        if m == w.size:
            return self._resample(w, self.rng)
        return inverse_cdf(w, (self.rng.random() + np.arange(m)) / m)

    def _inject(
        self,
        p_inj: float,
        lidar: LaserScan | None,
        semantic: SemanticScan | None,
        recovery: bool,
        prior: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> int:
        """Replace each particle with probability ``p_inj`` by an injected one; returns how many.

        ``prior``: ``(poses, log weights)`` of the predicted belief, before this update weighed it
        (``proposal_prior_weight`` scales routine proposals by its weight near each; None: the
        current set).

        A recovery (augmented MCL) draws from ``proposal_candidates`` candidates; the routine
        Mixture-MCL injection from ``min(proposal_candidates, max(10 r, r m))`` for ``m`` particles, ``r`` =
        ``proposal_candidates_per_particle`` (20: ``max(200, 20 m)``).
        """
        c = self.config
        mask = self.rng.random(self.n_particles) < p_inj
        m = int(mask.sum())
        if m == 0:
            return 0
        if c.injection == "scan":
            if self._proposal is None:
                self._proposal = ScanProposal(self.grid, self.sample_free)
            r = c.proposal_candidates_per_particle
            k = c.proposal_candidates if recovery else min(c.proposal_candidates, max(int(10 * r), int(r * m)))
            cand = self._proposal.candidates(k, semantic, c.proposal_semantic_frac, self.rng)
            ll_l, ll_s, _ = self.measurement_model.log_likelihood_terms(cand, lidar, semantic)
            new = self._proposal.draw(m, cand, c.likelihood_scale * (np.asarray(ll_l) + np.asarray(ll_s)), self.rng)
        else:
            new = self.sample_free(m)
        logw = self._logw.copy()
        logw[mask] = -math.log(self.n_particles) + (0.0 if recovery else math.log(c.proposal_weight))
        lam = c.proposal_prior_weight
        if not recovery and lam > 0.0:
            b = c.belief
            poses, logw_prior = prior if prior is not None else (self._poses, self._logw)
            near = prior_mass_near(poses, np.exp(logw_prior), new, b.cluster_bin_m, b.cluster_bin_theta_rad)
            with np.errstate(divide="ignore"):  # lam = 1 and no prior weight near: weight 0
                scaled = logw[mask] + np.log((1.0 - lam) + lam * np.minimum(near, 1.0))  # near <= 1 but rounding
            kept = logw[~mask]
            if np.isfinite(scaled).any() or np.isfinite(kept).any():  # else no weight would be left: unscaled
                logw[mask] = scaled
        self._poses = self._poses.copy()
        self._poses[mask] = new
        self._logw = logw - self._lse(logw)
        return m

    def audit_candidate_count(self) -> int:
        """Scan-proposal candidates an audit draws on this map (`MCLConfig.audit_candidates_per_m2`)."""
        c = self.config
        if c.audit_candidates_per_m2 <= 0.0:
            return c.audit_candidates
        return int(min(max(c.audit_candidates, round(c.audit_candidates_per_m2 * self.free_area_m2)), MAX_PARTICLES))

    def _audit(self, lidar: LaserScan | None, semantic: SemanticScan | None) -> tuple[float, int]:
        """The convergence audit of one update (`MCLConfig.audit_window`); ``(log ratio, added)``."""
        c = self.config
        b = self._summary()
        if not b.converged or self._was_converged:
            self._was_converged = b.converged
            return math.nan, 0
        if len(self._window) < self._window_least:
            return math.nan, 0  # too few scans since the lost hold to judge: not called converged yet
        self._window_least = 0
        self._was_converged = True
        # with the "spread" rule a belief can converge while no cluster reaches cluster_min_weight: audit it whole
        hyp = b.hypotheses[0] if b.hypotheses else Hypothesis(1.0, b.mean, b.cov, b.n_particles)
        outside_args = (2.0 * c.belief.cluster_bin_m, c.belief.cluster_bin_theta_rad)
        if self._cleared is not None and self.n_updates - self._cleared[1] < c.audit_window:
            if not audit.outside(hyp.mean[None], self._cleared[0], *outside_args)[0]:
                return math.nan, 0  # cleared within the window: the same scans would be audited again
        if self._proposal is None:
            self._proposal = ScanProposal(self.grid, self.sample_free)
        cand = self._proposal.candidates(self.audit_candidate_count(), semantic, c.proposal_semantic_frac, self.rng)
        ll_l, ll_s, _ = self.measurement_model.log_likelihood_terms(cand, lidar, semantic)
        last = self._screen_cleared
        screen = c.audit_screen and (
            last is None
            or self.n_updates - last[0] >= c.audit_screen_pause
            or (c.audit_screen_pause_place and audit.outside(hyp.mean[None], last[1], *outside_args)[0])
        )
        extra = None
        if screen:
            extra = audit.screened_places(
                self.measurement_model, self._window, c.likelihood_scale, hyp.mean, self.rng, *outside_args
            )
        alt = audit.best_alternative(
            self.measurement_model, self._window, c.likelihood_scale, self._poses, self._logw, hyp.mean,
            cand, np.asarray(ll_l) + np.asarray(ll_s), self.rng, *outside_args, places=c.audit_places, extra=extra,
        )  # fmt: skip
        ratio = math.nan if alt is None else alt.log_ratio
        kept = alt is not None and ratio >= -c.audit_margin
        if alt is not None and not kept and c.audit_blur_margin > 0:
            blurred = audit.window_log_likelihood(
                audit.screen_model(self.measurement_model), np.stack([hyp.mean, alt.pose]), self._window,
                c.likelihood_scale,
            )  # fmt: skip
            if blurred[1] - blurred[0] >= -c.audit_blur_margin:  # alike but for cell-sized map differences
                ratio, kept = float(blurred[1] - blurred[0]), True
        if not kept:
            self._cleared = (hyp.mean, self.n_updates)
            if self._audit_by_surprise and c.audit_after_surprise_once:
                self._audit_on = self._audit_by_surprise = False  # found again: tracking as before the surprise
            self._screen_cleared = (self.n_updates, hyp.mean.copy()) if screen else last
            return (math.nan if alt is None else alt.log_ratio), 0
        self._cleared = None
        self._screen_cleared = None
        m = c.cluster_min_particles
        new = audit.shaped_like(self._poses, np.exp(self._logw), hyp.mean, alt.pose, m, self.rng, *outside_args)
        added = math.log(hyp.weight) + min(ratio, 0.0)  # at most the hypothesis's weight
        logw = np.concatenate([self._logw, np.full(m, added - math.log(m))])
        self._poses = np.ascontiguousarray(np.vstack([self._poses, new]))
        self._logw = logw - self._lse(logw)
        self._was_converged = False
        return ratio, m  # the blurred fields' ratio when they kept the alternative

    # ------------------------------------------------------------ summary
    def _summary(self) -> Belief:
        """`summarize` of the current set, computed once per set (the set's arrays are replaced, never
        written, when it changes, so their identity says whether it did)."""
        return self._summary_of(self._poses, self._logw)

    def _summary_of(self, poses: np.ndarray, logw: np.ndarray) -> Belief:
        cached = self._summary_cache
        if cached is not None and cached[0] is poses and cached[1] is logw:
            return cached[2]
        b = summarize(poses, np.exp(logw), self.config.belief, self._belief_backend)
        self._summary_cache = (poses, logw, b)
        return b

    def _reported_summary(self) -> Belief:
        """The summary `belief` starts from: the current set's, or with ``belief_between_updates="odometry"`` after
        a ``predict`` the last update's (or init's) set's carried by the odometry since (`carried`)."""
        anchor = self._anchor
        if self.config.belief_between_updates == "exact" or anchor is None or anchor[0] is self._poses:
            return self._summary()
        return carried(self._summary_of(*anchor), self._since_update, self.config.belief)

    def belief(self) -> Belief:
        """Summary of the current particle set (see `filters.localization.belief`); with
        ``belief_between_updates="odometry"``, after a ``predict`` no update has followed, the last update's (or
        init's) set's summary carried by the odometry since (`filters.localization.belief.carried`). With
        ``belief.converged_min_updates = k > 1`` it is ``converged`` only if the current set meets
        the criterion and so did the set after each of the last ``k`` measurement updates
        (`converged_updates`); after an init, ``k`` updates must run first. With
        ``belief.converged_hold_weight`` a set that does not meet the criterion is ``converged`` while
        the last update's was and its heaviest hypothesis stays at that place with at least the hold
        weight (the hold's place moves with that hypothesis from update to update). With
        ``audited_convergence`` a set that meets the criterion is ``converged`` only once an update's
        audit has seen it (or a held convergence keeps it)."""
        self._require_particles()
        b = self._reported_summary()
        c = self.config
        k = c.belief.converged_min_updates
        if k > 1 and b.converged and self.converged_updates < k:
            b = replace(b, converged=False)
        if b.converged and c.audited_convergence and c.audit_window and self._audit_on and not self._was_converged:
            b = replace(b, converged=False)  # not audited yet: the next update's audit decides
        if not b.converged and self._holds(b):
            b = replace(b, converged=True)
        return b

    def _holds(self, b: Belief) -> bool:
        """Whether ``b``'s heaviest hypothesis keeps the convergence of the last update's
        (``belief.converged_hold_weight``; the belief module's docstring)."""
        c = self.config.belief
        if c.converged_hold_weight is None or self._held is None or not b.hypotheses:
            return False
        top = b.hypotheses[0]
        same = not audit.outside(top.mean[None], self._held, 2.0 * c.cluster_bin_m, c.cluster_bin_theta_rad)[0]
        return same and holds_as_converged(top, c, c.converged_hold_weight)
