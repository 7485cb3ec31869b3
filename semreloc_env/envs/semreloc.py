"""``SemReloc-v21`` (and ``-v20`` ... ``-v0``): active global relocalization with a semantic particle filter inside."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np

from filters.localization.likelihood_field import NegativeEvidenceConfig, cached_model
from filters.localization.mcl import MCLConfig, MonteCarloLocalizer
from filters.mapping.grid import GridMap
from filters.numbers import is_int
from filters.pose import wrap_float

from ..config import check_reward_weights
from ..layouts import LAYOUT_NAMES, check_layout_seed, get_layout
from ..lookalike import NoPlaceError, lookalike_kidnap
from ..map_world import check_map_matches_world
from ..maps import MAP_SOURCES, env_classes, is_ros_map_file, maps_for, names_a_layout, searched_ros_map
from ..scenarios import SCENARIOS, changed_obstacles
from ..world import as_pose
from .base import SemRelocBase, check_seed_use

RELOCALIZER_V1 = MCLConfig(
    n_particles=None,
    global_particles_per_m2=50.0,
    min_particles=500,
    max_particles=20000,
    kld=True,
    resample_mode="clustered",
    augmented=True,
    injection="scan",
    proposal_frac=0.05,
    lidar_on_rotation=False,
    likelihood_scale=0.06,
    places_follow_odometry=False,
)
"""The relocalizer of SemReloc-v1 to -v3 (`filters.localization.mcl.MCLConfig` with these overrides):
50 particles per m^2 of free space (500 to 20,000) with KLD sampling, clustered resampling,
5 % of the particles replaced every update by poses drawn from the current scan (semantic
detections first) plus augmented-MCL recovery, the lidar factor left out of turn-in-place
updates, tempering 0.06; the places remembered between updates stay where the last update left them
(``places_follow_odometry=False``, kept by every later version up to v18 so their episodes stay as they were; it
matters only from v5's audits and v6's holds on; v19 turns it on). Chosen on tuning seeds 5000+ and procedural_sym layouts 100-104
(docs/relocalizer_eval.md, "Choosing the defaults"); evaluated on other seeds and layouts."""

RELOCALIZER_V4 = dataclasses.replace(RELOCALIZER_V1, negative_evidence=NegativeEvidenceConfig(p_detect=0.8))
"""The relocalizer of SemReloc-v4: `RELOCALIZER_V1` plus evidence from mapped objects the camera
did not see (`filters.localization.likelihood_field.NegativeEvidenceConfig`, ``p_detect=0.8``;
docs/relocalizer.md, "Negative evidence"). Chosen on the tuning cases of
``scripts/evaluate_active.py --seed-set tuning``; evaluated on the held-out ones."""

RELOCALIZER_V5 = dataclasses.replace(RELOCALIZER_V4, audit_window=20, audit_margin=1.0)
"""The relocalizer of SemReloc-v5: `RELOCALIZER_V4` plus the convergence audit
(`filters.localization.audit`: at the update where the belief becomes converged, a place outside
its hypothesis that explains the last 20 updates' scans within 1 nat of it is added as a second
hypothesis; docs/relocalizer.md, "Convergence audit"). Chosen on the tuning cases of
``scripts/evaluate_active.py --seed-set tuning``; evaluated on the held-out ones."""

RELOCALIZER_V6 = dataclasses.replace(
    RELOCALIZER_V5,
    belief=dataclasses.replace(RELOCALIZER_V5.belief, converged_hold_weight=0.85),
    surprise_ratio=0.3,
)
"""The relocalizer of SemReloc-v6: `RELOCALIZER_V5` whose belief *holds* a convergence
(`filters.localization.belief.BeliefConfig.converged_hold_weight` 0.85: once called converged, the
belief stays so while its heaviest hypothesis stays at the same place with at least 85 % of the
weight) until a *surprise* (`MCLConfig.surprise_ratio` 0.3: an update whose scans fit the particles
far worse than of late ends the hold and restarts the convergence audit's window);
docs/relocalizer.md, "Holding a convergence". Chosen on tuning seeds 100-111 of the lab,
``three_rooms``, ``twin_rooms`` and procedural layouts; evaluated on the seeds of
``scripts/evaluate_relocalizer.py`` and the held-out pairs of ``scripts/evaluate_active.py``."""

RELOCALIZER_V7 = dataclasses.replace(
    RELOCALIZER_V6, audited_convergence=True, audit_places=16, audit_candidates_per_m2=14.0
)
"""The relocalizer of SemReloc-v7 and -v8: `RELOCALIZER_V6` whose convergence audit searches harder and comes
first. The audit refines the best poses of 16 different places on each side on their own before its
coarse-to-fine search (`MCLConfig.audit_places`): in every wrong first convergence of the tuning pairs
traced on v6, a look-alike place that explained the window's scans as well as the hypothesis had been
dropped after one rough guess. And a set that comes to meet the "converged" criterion between updates
(a prediction alone) is called converged only after the next update's audit
(`MCLConfig.audited_convergence`); v6 called it converged at once, for up to a few steps, in layouts no
sensor can tell apart. And the audit draws at least 14 scan-proposal candidates per m^2 of free space
(`MCLConfig.audit_candidates_per_m2`; a lab-size map keeps its 2000), so they cover a large hall as
densely as the maps the audit was tuned on. Chosen on the tuning cases of ``scripts/evaluate_active.py --seed-set tuning``
and layouts written by a reviewer; evaluated on the held-out pairs (docs/relocalizer.md, "Audit
first, search wider")."""

RELOCALIZER_V9 = dataclasses.replace(RELOCALIZER_V7, audit_screen=True, audit_screen_pause=100)
"""The relocalizer of SemReloc-v9: `RELOCALIZER_V7` whose convergence audit also screens the whole map for
a look-alike place (`MCLConfig.audit_screen`, `filters.localization.audit.screened_places`): a grid of
poses scored with blurred likelihood fields, the best places refined; not again for 100 updates after a
screen that found nothing (`MCLConfig.audit_screen_pause`). In 6 of the 7 wrong first
convergences of the explorer on 900 tuning pairs of v8, the true place explained the audit's window as
well as the hypothesis, but no scan-proposal candidate or particle lay within 0.24-0.9 m and 0.2-0.45 rad
of it, so the audit never found it (docs/relocalizer.md, "An audit that screens the whole map"). Chosen
on the tuning cases of ``scripts/evaluate_active.py --seed-set tuning`` and layouts of outside testers;
evaluated on the held-out pairs."""

RELOCALIZER_V10 = dataclasses.replace(RELOCALIZER_V9, audit_screen_pause_place=True)
"""The relocalizer of SemReloc-v10 and -v11: `RELOCALIZER_V9` whose screen pauses only while the belief stays at the
place the last screen cleared (`MCLConfig.audit_screen_pause_place`; v9 skipped the screen for 100 updates
after it found nothing, wherever the belief converged next). ``audit_blur_margin`` (off) trades successes for
fewer wrong convergences between places a robot's map holds slightly differently (docs/relocalizer.md,
"Corridor pods: look-alike places whose maps differ")."""

RELOCALIZER_V12 = dataclasses.replace(RELOCALIZER_V10, audit_after_surprise=True)
"""The relocalizer of SemReloc-v12: `RELOCALIZER_V10` whose convergence audit also runs in a tracking episode
once a surprise (a kidnapping) has shown the pose lost (`MCLConfig.audit_after_surprise`). A global start
audits every convergence as v10's does, with the same bits."""

RELOCALIZER_V13 = dataclasses.replace(RELOCALIZER_V12, surprise_own_average=True)
"""The relocalizer of SemReloc-v13: `RELOCALIZER_V12` whose surprise test compares with an average of its own,
which augmented MCL's injections do not restart (`MCLConfig.surprise_own_average`). A global episode runs as
v12's up to its first convergence, which ends it when it is correct."""

RELOCALIZER_V14 = dataclasses.replace(RELOCALIZER_V13, semantic_surprise_ratio=0.4)
"""The relocalizer of SemReloc-v14: `RELOCALIZER_V13` with the camera's own surprise test
(`MCLConfig.semantic_surprise_ratio` 0.4: two updates in a row, each with at least 3 labelled camera beams, whose
average semantic likelihood per labelled beam falls below 0.4 times its fast average are a surprise). It sees a
kidnapping that only the objects' classes reveal, which the all-beam test does not. Chosen on class-only
kidnappings in ``three_rooms`` and ``twin_rooms`` and tracking episodes in four built-in layouts; evaluated on an
outside tester's layout (docs/relocalizer.md, "A surprise test of the camera's own")."""

RELOCALIZER_V15 = dataclasses.replace(RELOCALIZER_V14, audit_after_surprise_once=True)
"""The relocalizer of SemReloc-v15: `RELOCALIZER_V14` whose audit, turned on in a tracking episode by a surprise,
turns off again once it has cleared a convergence (`MCLConfig.audit_after_surprise_once`): the pose is found again
and the episode tracks as before its surprise. v14's audit stayed on, and at a later convergence whose window of
scans held no telling object it could add a look-alike place back to a belief converged at the truth. A global
start audits every convergence, as v14's. Chosen on class-only kidnappings in ``three_rooms``, ``twin_rooms`` and a
half-turn layout of our own; evaluated on an outside tester's four layouts (docs/relocalizer.md, "After a
surprise, an audit until it clears")."""

RELOCALIZER_V16 = dataclasses.replace(RELOCALIZER_V15, audit_after_lost_hold=True)
"""The relocalizer of SemReloc-v16: `RELOCALIZER_V15` in which a held convergence that ends without a surprise also
turns the audit on in a tracking episode (`MCLConfig.audit_after_lost_hold`), as a surprise does. A kidnapping that
neither surprise test notices (into a look-alike place whose scans differ mostly in beams without a return, or
whose classes the camera has not yet judged) still loses the hold, and the next convergence is audited as a
relocalization. v15 called it unaudited, and in an outside tester's pillar hall and class-only rooms converged
again at a look-alike place. A global start audits every convergence, as v15's: its episodes are v15's. Chosen on
the tester's layouts; evaluated on 21 layouts of earlier testers (docs/relocalizer.md, "A hold lost without a
surprise")."""

RELOCALIZER_V17 = dataclasses.replace(RELOCALIZER_V16, hold_init_pose=True)
"""The relocalizer of SemReloc-v17: `RELOCALIZER_V16` whose tracking start holds the pose it is given as a converged
hypothesis and arms the surprise tests (`MCLConfig.hold_init_pose`). v16's tracking start was often not converged
(its cloud split, about 94 % in the heaviest hypothesis), so a kidnapping before the belief first met the 95 % rule
by itself lost no hold, raised no surprise, and the next convergence went unaudited. A global start holds nothing,
as v16's: its episodes are v16's. Chosen on an outside tester's layouts (docs/layouts/outside_v16); evaluated on a
third tester's layouts (docs/relocalizer.md, "A tracking start holds its pose")."""

RELOCALIZER_V18 = dataclasses.replace(RELOCALIZER_V17, lost_hold_window=5)
"""The relocalizer of SemReloc-v18: `RELOCALIZER_V17` in which the audit a hold lost without a surprise turns on
judges only the scans since the hold began to fade, and only once it has five (`MCLConfig.lost_hold_window`). v17's
judged the last 20 updates' scans, which after an unnoticed kidnapping came mostly from before it and fitted the old
track, and cleared convergences at look-alike places. Global starts never lose a hold with the audit off: their
episodes are v17's. Chosen on look-alike kidnappings (`semreloc_env.lookalike`) in three outside testers' layouts;
evaluated on 21 layouts of earlier testers (docs/relocalizer.md, "The window's old scans")."""

RELOCALIZER_V19 = dataclasses.replace(RELOCALIZER_V18, kld_epsilon=0.15, places_follow_odometry=True)
"""The relocalizer of SemReloc-v19: `RELOCALIZER_V18` whose KLD sampling allows three times the error
(``kld_epsilon`` 0.15 instead of 0.05), so a spread belief holds fewer particles (a mean of 675 instead of 1,154 over
the relocalizer evaluation's tuning episodes; right after a global reset in the lab 1,550-4,000 instead of
17,800-20,000, ten seeds); and whose remembered places (a held convergence's, a place an audit cleared) move with the odometry between
updates (``places_follow_odometry``). Chosen on the relocalizer evaluation's tuning seeds; evaluated on its reported
seeds and the 930 held-out active pairs (docs/relocalizer.md, "SemReloc-v19")."""

RELOCALIZER_V20 = dataclasses.replace(RELOCALIZER_V19, belief_between_updates="odometry")
"""The relocalizer of SemReloc-v20: `RELOCALIZER_V19` whose belief, on the steps the motion gate skips the measurement
update (most of them), is the last update's carried by the odometry since (``belief_between_updates="odometry"``, as
AMCL reports between updates) instead of the moved set summarised again. For the same actions the particles, weights
and updates are v19's bit for bit; a step without an update costs about a third less. On the relocalizer evaluation's
4,460 reported episodes (belief-blind policies) no outcome or time to success changed (docs/performance.md, "The
belief carried between updates")."""

RELOCALIZER_V21 = dataclasses.replace(RELOCALIZER_V20, global_particles_per_m2=25.0, predict_when_still=False)
"""The relocalizer of SemReloc-v21: `RELOCALIZER_V20` with less work at a global start and on still steps: a global
start draws 25 particles per m^2 of free space instead of 50 (``global_particles_per_m2``; the sparser draw occupies
fewer of KLD's bins, so its first resampling keeps fewer too: 553-2,638 in the lab instead of 1,554-3,982; with
``n_particles`` given nothing changes there), and a step without motion (a zero odometry increment) leaves the
particles as they are without drawing their zero motion noise (``predict_when_still=False``). Chosen on the
relocalizer evaluation's tuning seeds; evaluated on its reported seeds and more: the same outcomes, with a possible
small cost after a kidnapping that follows a global start (docs/performance.md, "SemReloc-v21")."""

DEFAULT_RELOCALIZER = dataclasses.replace(
    RELOCALIZER_V21,
    motion=dataclasses.replace(RELOCALIZER_V21.motion, exact_small_moves=True),
    kld_one_sequence=True,
)
"""The relocalizer of SemReloc-v22: `RELOCALIZER_V21` with two corrections found by an outside audit. Its motion
model moves an odometry step under ``min_trans_m`` (1 cm) in the step's own direction
(`filters.motion.odometry.OdometryMotionConfig.exact_small_moves`; v21 and older took a 5 mm step backwards as 5 mm
forwards), as the env's simulated odometry now reads it; and KLD sampling draws one sequence, as Fox's algorithm does
(``kld_one_sequence``; v21 and older drew a second sequence from scratch when the first ``max(2 N, 4 min_particles)``
draws had not met the bound, which moved the set size down). docs/relocalizer.md, "SemReloc-v22", has the
measurements."""

LEGACY_RELOCALIZER = MCLConfig(likelihood_scale=0.03, belief={"converged_rule": "spread"})
"""SemReloc-v0's relocalizer: the plain `MCLConfig` (2000 particles, global systematic
resampling, no KLD, no injection of any kind) tempered with 0.03, and "converged" = small
spread of the whole set."""

LEGACY_RELOCALIZER_OVERRIDES = LEGACY_RELOCALIZER.as_dict()
"""Every field of `LEGACY_RELOCALIZER` as ``relocalizer=`` overrides (for before/after
comparisons in one env id)."""

KIDNAP_TO_LOOKALIKE = "lookalike"
"""The reset option ``kidnap_pose`` that teleports to `semreloc_env.lookalike.lookalike_kidnap` of the pose at the
kidnap step (a kidnapping the scans need not give away)."""
SUCCESS_POSITION_M = 0.5
SUCCESS_HEADING_RAD = math.radians(15.0)


@dataclasses.dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms (see the env docstring)."""

    time: float = -0.01
    collision: float = -0.5
    entropy: float = 0.05
    success: float = 1.0
    wrong_convergence: float = -0.05

    def __post_init__(self) -> None:
        check_reward_weights(self)


class SemRelocEnv(SemRelocBase):
    """Semantic active relocalization of a differential-drive robot in a 2D world.

    ## Description
    A pymunk world built from a *layout* (walls, doors, chairs, trash bins,
    cabinets) holds a disc robot with a 360 deg lidar, a forward semantic camera
    (paper 004's semantic pseudo-laser) and wheel odometry. Inside the env runs a
    Monte Carlo relocalizer (`filters.localization.mcl.MonteCarloLocalizer`) whose
    weights multiply a lidar likelihood field with a per-class semantic
    likelihood field. By default every episode is a *global* relocalization:
    the belief starts uniform over the map's free space, and the policy should
    move so that it converges fast and to the right place.

    ## Action Space
    ``action_type="discrete"`` (default): ``Discrete(4)`` — 0 forward at
    ``robot.max_linear_mps``, 1 turn left, 2 turn right (at ``robot.max_angular_rps``), 3 stop.
    ``action_type="continuous"``: ``Box(-1, 1, (2,))`` — ``(v, omega)`` scaled by the same maxima.
    An invalid action (out of range, NaN, the wrong shape or kind) raises ``ValueError`` and changes nothing.
    Continuous actions are checked by value, not dtype: any two finite real numbers (not bools) in ``[-1, 1]``
    are taken, int64 and float64 arrays included, which Gymnasium's ``Box.contains`` refuses; values within
    ``semreloc_env.envs.spaces.ACTION_BOUND_SLACK`` (1e-5) of a bound are clipped to it.

    ## Observation Space
    ``Dict`` of float32 boxes and one ``MultiDiscrete`` (``SemReloc-v2``, ``observation_layout = "typed"``):

    | key | space | shape | range | meaning |
    |---|---|---|---|---|
    | ``lidar`` | Box float32 | ``(lidar.n_beams,)`` | ``[0, range_max_m]`` m | ranges, evenly spaced over ``fov_rad`` from ``-fov/2``; no return reads ``range_max_m`` |
    | ``odometry`` | Box float32 | ``(3,)`` | ``+-(1 m, 1 m, pi)`` | noisy increment ``(dx, dy, dtheta)`` since the last step, in the previous robot frame, clipped to the bounds (faster robots: the filter still gets it whole) |
    | ``semantic_class`` | MultiDiscrete int64 | ``(camera.n_beams,)`` | ``{0..4}`` | class label per pseudo-laser beam (0 none, 1 door, 2 chair, 3 trash_bin, 4 cabinet) |
    | ``semantic_range`` | Box float32 | ``(camera.n_beams,)`` | ``[0, camera.range_max_m]`` m | pseudo-laser range per beam, to the first surface (a wall too, with class 0); ``range_max_m`` where nothing is in range (and where a labelled beam's noisy depth was clipped: it keeps its class) |

    ``SemReloc-v1`` and ``-v0`` (``observation_layout = "flat"``) have one float32 Box ``semantic`` of
    shape ``(2 * camera.n_beams,)`` instead of the last two: the ranges, then the labels as floats.
    `semreloc_env.envs.spaces.semantic_parts` reads either.

    Belief features for a policy: wrap with `semreloc_env.wrappers.BeliefObservation`.

    ## Rewards
    A dict of named terms in ``info["rewards"]``, weighted by ``reward_weights``
    (`RewardWeights`); the reward is their sum:
    ``time`` (constant per step), ``collision`` (robot touched an obstacle),
    ``entropy`` (drop of the belief's pose-histogram entropy, nats),
    ``success`` (once, when the belief converges within 0.5 m and 15 deg of the truth;
    in a tracking episode only after a kidnap), ``wrong_convergence`` (every step the
    belief is converged but farther than that from the truth: the entropy term alone
    would pay for collapsing onto a look-alike place).

    ## Starting State
    A uniformly random free pose, or ``options={"pose": (x, y, theta)}``. The
    belief is uniform over free space, or, with ``options={"tracking": True}``,
    concentrated around the true pose (tracking).

    ## Episode End
    Terminated on success (see Rewards) in a global relocalization, or in a tracking
    episode after the kidnap. Truncated by the time limit (``max_episode_steps``, 400 at registration).
    ``step()`` after ``terminated`` is allowed and continues the same episode (the robot drives, the
    filter updates, ``terminated`` stays True and the success reward is not paid again): the relocalizer
    evaluation watches the belief on that way. Call ``reset()`` to start a new episode.

    ## Info
    ``pose`` true pose (m, m, rad); ``belief`` the filter's summary
    (`filters.localization.belief.Belief.as_dict`: ``converged`` — one tight hypothesis
    holds >= 95 % of the mass, or, since v6, still >= 85 % at the place an update last called
    converged —, ``hypotheses`` by weight, ``estimate``, spread, entropy, ESS; since v20, on a step whose
    measurement update the motion gate skipped, the last update's summary carried by the odometry since:
    ``MCLConfig.belief_between_updates``);
    ``pose_error`` ``{"position": m, "heading": rad}`` of the belief's estimate (its heaviest
    hypothesis); ``is_success`` (the success test below has been met in this episode); ``mcl`` the last update's diagnostics (`filters.localization.mcl.UpdateDiagnostics`;
    a value not computed in this step, such as ``ess`` when the motion gate skipped the update, is left
    out; ``SemReloc-v1``/``-v0`` put None there instead); ``rewards``;
    ``collided``; ``kidnapped`` (True from the kidnap step on).

    ## Arguments
    * ``layout``: ``"lab"`` (default, unless ``map_source`` is a map), another built-in
      (``"twin_rooms"``, ``"three_rooms"``, ``"open_hall"``), a procedural kind (``"procedural"``,
      ``"procedural_sym"``, ``"procedural_lookalike"``, ``"procedural_ring"``, ``"procedural_corridor"``;
      ``layout_seed`` seeds them), the name of a layout file on ``$SEMRELOC_LAYOUT_PATH``, a ``.json``/``.yaml`` path, a dict, a `Layout`, or a
      ROS map ``.yaml`` / GridMap (the world it shows). `semreloc_env.layouts.LAYOUT_NAMES` lists the names.
    * ``action_type``: ``"discrete"`` or ``"continuous"``.
    * ``robot``, ``physics``, ``lidar``, ``camera``, ``odometry``: dicts of overrides of
      `RobotParams`, ``PhysicsParams``, ``LidarParams``,
      ``CameraParams`` and `filters.motion.odometry.OdometryMotionConfig` (the simulator's noise).
    * ``relocalizer``: dict of overrides of `DEFAULT_RELOCALIZER`, a `filters.localization.mcl.MCLConfig`
      (e.g. ``n_particles``); an MCLConfig instance replaces it whole.
    * ``semantic``: False runs the relocalizer lidar-only (the comparison of paper 004); None
      (default) keeps the relocalizer's ``use_semantic`` (True unless overridden there).
    * ``map_source``: ``"mapping"`` (default; maps built by a simulated mapping run, so map and
      world disagree as on a robot), ``"perfect"`` (rasterised layout), a ROS map ``.yaml`` / ``.yml``
      path, a GridMap, or another layout (name or file; its mapping run is the map). With
      ``layout`` unset, a map file or GridMap also gives the world (traced from its occupied
      cells, `semreloc_env.map_world`); a map whose extent or frame does not fit the world is an error.
    * ``scenario``: ``"nominal"`` or ``"changed"`` (obstacles in the world that the map lacks, paper 004).
    * ``reward_weights``: dict of overrides of `RewardWeights`.
    * ``render_mode``: ``"rgb_array"`` or ``"human"`` (a matplotlib window, paced to ``metadata["render_fps"]``).
      ``metadata["render_fps"]`` is the control rate ``physics.control_hz`` (one frame per step), so
      ``gymnasium.wrappers.RecordVideo`` (extra ``video``: moviepy) plays in real time.
    Unknown arguments or keys raise ``TypeError`` / ``ValueError``.

    ## Reset options
    ``pose``; ``tracking`` (bool); ``kidnap_at_step`` (int >= 1, at most the time limit when
    made by ``gym.make``: at that step the robot is teleported without telling the filter) and ``kidnap_pose`` (default: random free pose;
    ``"lookalike"``: the place at least 3 m away, or less in a small layout, whose all-round view is most like the
    robot's view where it stands at that step, `semreloc_env.lookalike.lookalike_kidnap`, searched in about 0.2 s).
    A global episode (``tracking`` not set) ends at its first correct convergence, often before
    ``kidnap_at_step``: then no kidnap happens (``info["kidnapped"]`` stays False). To kidnap a
    localized robot, reset with ``tracking=True``. The relocalizer notices a kidnap from the scans' fit
    (its surprise tests, armed from the start of a tracking episode and once the belief has been converged in a
    global one), one that only the objects' classes reveal
    once two camera updates in a row contradict the believed classes; one into an exact look-alike goes
    unnoticed (docs/relocalizer.md, "What the surprise test cannot see", "A surprise test of the camera's own").
    When the held convergence of a kidnap it did not notice fades, the next convergence is audited all the same
    (v16; "A hold lost without a surprise"). One kidnap per episode; ``info["kidnapped"]`` says from which step.
    In a layout too cramped for it, the kidnap step finds no place to take the robot to: that step raises
    (``ValueError``, `semreloc_env.lookalike.NoPlaceError` for ``"lookalike"``) and changes nothing, as does every
    later one, until a reset.
    A bad option or seed raises ``ValueError`` and leaves the episode as it was; ``gym.make``
    checks them in its outermost wrapper (`semreloc_env.wrappers.CheckedReset`), so the
    time limit keeps counting the old episode; so does a reset that fails inside the env (no free place for a
    random start).

    ## Version History
    * v22: two corrections (`DEFAULT_RELOCALIZER`: `RELOCALIZER_V21` with ``motion.exact_small_moves`` and
      ``kld_one_sequence``). An odometry step under 1 cm moves in its own direction, in the simulated odometry (the
      ``odometry`` observation) and in the filter's motion model: v21 and older took it along the heading. So a robot
      backing at ``v`` between -0.2 and 0 (continuous actions) read forwards (30 such steps from a known pose left
      v21's belief 0.27 m off, v22's within 2 cm), and the filter took the small translation that odometry noise gives
      a turn on the spot (std about 1 cm; two thirds of turns under 1 cm) forwards, a drift of a few mm per turn. KLD
      sampling draws one sequence, as Fox's algorithm: v21's retry drew a second one from scratch, which shrank some
      sets. Discrete actions give v21's observations (their only steps under 1 cm are turns, whose true translation is
      zero); the filter differs. On the relocalizer evaluation's 2,230 held-out episodes: 1,959 successes against
      v21's 1,945 (p = 0.11), none wrong at the end, the median position error 0.041 m against 0.050 m (lower in 67 %
      of episodes), the same steps to success and CPU per step. Under a continuous policy that jitters back and forth
      (an untrained Gaussian policy's actions), the motion gate sees the true net motion where v21 counted the reverse
      steps forwards, so v22 updates less often and converges later: 356 successes of 930 held-out pairs within 200
      steps against v21's 380 (p = 0.005), nearer the truth (docs/relocalizer.md, "SemReloc-v22").
    * v21: the relocalizer does less work at a global start and on still steps (`RELOCALIZER_V21`: `RELOCALIZER_V20`
      with ``global_particles_per_m2=25.0`` and ``predict_when_still=False``): a global start draws 25 particles per m^2
      of free space instead of 50 (3,484 instead of 6,969 in the lab; the first resampling keeps 553-2,638 instead of
      1,554-3,982, ten seeds), and a step with a zero odometry increment (a stop, or a robot pinned against a wall)
      leaves the particles as they are without drawing their motion noise, which is zero. Every episode's filter draws
      differ from v20's from the reset on (the world, sensors and observations for the same actions are v20's). A global
      `reset()` costs about a third less (3.5 against 5.6 ms in the lab; 0.65-0.68x timed in turn on the same seeds), a
      batched random walk 1.00-1.15x the robot-steps per CPU-second; long episodes gain nothing measurable. On the
      relocalizer evaluation's 2,230 reported episodes the outcomes and steps to success are v20's within chance (1,945
      successes against 1,947, no wrong final convergence in either). After a global start and a kidnapping the belief
      briefly converged at a wrong place and recovered in 14 of 2,400 held-out episodes against v20's 4: a possible
      small cost, not established (docs/performance.md, "SemReloc-v21"). Maps, worlds, observation spaces, rewards and
      info keys are v20's (`SemRelocEnvV20` is v20).
    * v20: on the steps the motion gate skips the measurement update (83 % of a random walk's in the lab), the belief
      in ``info``, the observation wrappers and the reward is the last update's carried by the odometry since
      (`RELOCALIZER_V20`: `RELOCALIZER_V19` with ``belief_between_updates="odometry"``; as AMCL reports its pose
      between updates), not the moved particle set summarised again: its entropy and hypotheses stay the update's,
      its means and covariances move with the odometry, and "converged" no longer flickers off for a step as the
      moved set spreads (after a kidnapping it holds the old place until the next update). For the same actions the
      particles, weights, updates, observations and random draws are v19's bit for bit (a policy that reads the
      belief can act otherwise, and then the episode differs: the viewpoint planner on a lab seed succeeded in 23
      steps instead of 25); a step without an update costs about a third less (1.05-1.27x the batched robot-steps per
      CPU-second under random actions, 6 % under the evaluation's policies). On 4,460 reported evaluation episodes
      with policies that do not read the belief every outcome and time to success is v19's (docs/performance.md). Maps, worlds,
      observation spaces, rewards and info keys are v19's (`SemRelocEnvV19` is v19).
    * v19: the simulated wheel odometry no longer reads a slide along a wall (`semreloc_env.sensors.Odometry`,
      ``reads_slides=False``: the increment projected on the direction of an arc without slip). v18's odometry read
      the true increment, and the rot1-trans-rot2 model read a 1.7 cm slide across the heading as a quarter turn,
      a step and a quarter turn back, with about 1 m of translation noise: an outside reviewer's tracking robot
      pushing into a wall at 72 deg ended 5.8 m off. The relocalizer's KLD sampling allows three times the error
      (``kld_epsilon`` 0.15), so a spread belief holds fewer particles, and its remembered places move
      with the odometry (`RELOCALIZER_V19`: `RELOCALIZER_V18` with both). Every episode changes; outcomes
      on held-out seeds in docs/relocalizer.md, "SemReloc-v19". Maps, worlds, observations, rewards and info keys
      are v18's (`SemRelocEnvV18` is v18).
    * v18: when a held convergence fades without a surprise in a tracking episode, the audit it turns on judges only
      the scans since the set last met the 95 % rule by itself, and calls nothing converged until it has five
      (`DEFAULT_RELOCALIZER`: `RELOCALIZER_V17` with ``lost_hold_window=5``). v17's audit judged the last 20
      updates' scans: after a kidnapping no test noticed, most came from before it, fitted the old track, and the
      audit cleared convergences at look-alike places (look-alike kidnappings in 21 earlier outside testers'
      layouts: converged again at a wrong place 25 -> 18 of 630; plain tracking there is called converged 5 % less
      often, never wrongly in either; docs/relocalizer.md, "The window's old scans"). Global episodes run as
      v17's. Maps, worlds, sensors, observations, rewards and info keys are v17's (`SemRelocEnvV17` is v17).
    * v17: a tracking start holds the pose it is given (the true pose) as a converged hypothesis and arms the
      surprise tests from the first update (`RELOCALIZER_V17`: `RELOCALIZER_V16` with ``hold_init_pose``), so
      ``info["belief"]["converged"]`` is True from the reset on while the heaviest hypothesis keeps the pose. v16's
      tracking start was converged only once its cloud had at least 95 % in one hypothesis (often not at the
      reset): until then a kidnapping lost no hold and raised no surprise, and the next convergence went
      unaudited, in an outside tester's look-alike layouts at a wrong place (docs/relocalizer.md, "A tracking start
      holds its pose"). Global episodes run as v16's. Maps, worlds, sensors, observations, rewards and info keys
      are v16's (`SemRelocEnvV16` is v16).
    * v16: a held convergence that ends without a surprise (its hypothesis fades below the hold weight or leaves
      its place, and the belief is not converged elsewhere) turns the convergence audit on in a tracking episode, as a surprise does, and off again once it
      has cleared a convergence (`RELOCALIZER_V16`: `RELOCALIZER_V15` with ``audit_after_lost_hold``). A
      kidnapping that neither surprise test noticed (into a look-alike place whose scans differ mostly in beams
      without a return, or before the camera's test has judged an update) ended the hold all the same, and v15
      called the next convergence unaudited: in an outside tester's pillar hall and class-only rooms it converged
      again at a look-alike place (docs/relocalizer.md, "A hold lost without a surprise"). Global episodes run as
      v15's; a tracking episode's belief is called converged less often after a hold fades. Maps, worlds, sensors,
      observations, rewards and info keys are v15's (`SemRelocEnvV15` is v15).
    * v15: the audit a surprise turns on in a tracking episode (a kidnapping) turns off again once it has cleared
      a convergence (`RELOCALIZER_V15`: `RELOCALIZER_V14` with ``audit_after_surprise_once``), as before the
      surprise. v14's stayed on until the next reset, and at a later convergence whose window of scans held no
      telling object it could add a look-alike place (a half-turned twin room) back to a belief converged at the
      truth, so some episodes ended unconverged (docs/relocalizer.md, "After a surprise, an audit until it
      clears"). Global episodes, and tracking episodes without a surprise, run as v14's. Maps, worlds, sensors,
      observations, rewards and info keys are v14's (`SemRelocEnvV14` is v14).
    * v14: the relocalizer also has a surprise test of the camera's own (`RELOCALIZER_V14`: `RELOCALIZER_V13`
      with ``semantic_surprise_ratio=0.4``): two updates in a row whose labelled camera beams the belief explains
      far worse than of late are a surprise, with the consequences of the all-beam test's. v13's test judged all
      beams together, and the lidar's 60 outnumber the few labelled camera beams, so a kidnapping into a room of
      the same walls and furniture shapes but other classes raised no surprise, and the belief's held convergence
      kept it in the old room while the camera contradicted it (docs/relocalizer.md, "A surprise test of the
      camera's own"). ``info["mcl"]`` gains ``semantic_surprise``, ``w_surprise`` and ``w_semantic`` (in every
      version; ``w_semantic`` only in steps where that test judged an update). A global episode runs as v13's up
      to its first convergence. Maps, worlds, sensors, observations and rewards are v13's (`SemRelocEnvV13` is
      v13).
    * v13: the relocalizer's surprise test (a scan the belief explains far worse than of late: a kidnapping)
      compares with an average of its own (`RELOCALIZER_V13`: `RELOCALIZER_V12` with
      ``surprise_own_average``). v12's compared with augmented MCL's fast average, which AMCL's rule restarts
      after every update whose fast average fell below the slow one, by any amount (6-9 % of a tracking
      episode's lidar updates came right after such a restart); a restarted average starts at the next
      update's value, so a kidnapping right after a restart, or after turn-in-place updates without the lidar,
      became the new normal: no surprise, no audit, and the belief could converge at a wrong place (the three
      wrong re-convergences after kidnappings in v12's evaluation; docs/relocalizer.md, "The surprise test's own average"). A global
      episode runs as v12's up to its first convergence, so the evaluations' global starts, which end there
      when it is correct, are v12's. Maps, worlds, sensors, observations, rewards and info keys are v12's
      (`SemRelocEnvV12` is v12).
    * v12: the map of ``map_source="mapping"`` (the default) or of another layout comes from the mapping run's
      version 6 (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`), whose drive also enters passages that fall
      between its 0.6 m lattice's rows and columns (`semreloc_env.mapping_run.mapping_drive`'s ``narrow``). A
      1 m corridor could get no waypoint: the drive never entered it and the lidar mapped its walls from its
      ends only, in dashes, so two identical corridors got maps whose difference the relocalizer read as
      evidence (an outside tester's corridor pods: a scan scored at its true pose and at the look-alike
      pose differed by 0.085 tempered nats, standard deviation over 400 poses, against 0.015 now and 0.030
      on the layout's perfect raster). Every map changes (the drive is 0-38 % longer, most walls come out more complete), so episodes differ
      from v11's. And in a tracking episode (``options={"tracking": True}``) the convergence audit starts at
      the first surprise, a scan the belief explains far worse than of late (a kidnapping): the belief's next
      convergence is a relocalization and is audited as a global start's are (`RELOCALIZER_V12`:
      `RELOCALIZER_V10` with ``audit_after_surprise``). v11 audited no convergence in a tracking episode,
      and after a kidnapping into an outside tester's four-fold symmetric hall the explorer's belief
      converged at a quarter-turned image of the truth in 5 of 16 episodes (0 of 16 now; docs/relocalizer.md,
      "After a kidnapping"). Global starts give v11's episodes on v12's maps. Worlds, sensors, observations,
      rewards and info keys are v11's (`SemRelocEnvV11` is v11); docs/maps.md, "Narrow passages".
    * v11: the map of ``map_source="mapping"`` (the default) or of another layout comes from the mapping run's
      version 5 (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`): after the scans, the lidar's beams without
      a return clear, up to the first surface the returns marked, the cells that returns crossed too rarely
      to call free (`filters.mapping.occupancy.OccupancyMapper.clear_unobserved`). Space that returns
      cross too rarely (the middle of an outside tester's 24 m x 16 m hall, 6-8 m from the walls: 16.5 m^2)
      was left unknown, so the relocalizer could neither draw its first particles nor inject any there. Elsewhere a
      map changes in a few shadowed cells near objects, if at all (the lab's, ``twin_rooms``', ``open_hall``'s
      and ``three_rooms``' not at all; 7 of 120 held-out procedural maps in 1-8 cells), so episodes on a
      changed map differ from v10's. The relocalizer, worlds, sensors, observations, rewards and info keys
      are v10's (`SemRelocEnvV10` is v10); docs/maps.md, "Unobserved space".
    * v10: the map of ``map_source="mapping"`` (the default) or of another layout comes from the mapping run's
      version 4 (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`): a class cell stays only if a cell of its
      class within 0.1 m was marked with probability >= 0.9. The camera mislabels a whole object in 5 % of
      its frames; each surface cell of that object seen in such a frame got one hit of the wrong class,
      and the cells the drive saw rarely kept it: 1-20 stray class cells per map, on other objects'
      surfaces, which a mislabelled detection of the robot then matched (an outside tester: 5 of 120
      spinning episodes first converged in a shifted twin room). And the convergence audit's screen
      pauses after it found nothing only while the belief stays at the place it cleared
      (`RELOCALIZER_V10`: `RELOCALIZER_V9` with ``audit_screen_pause_place``); v9 skipped it for 100
      updates wherever the belief converged next. Worlds, sensors, observations, rewards and info keys
      are v9's (`SemRelocEnvV9` is v9); docs/relocalizer.md, "Maps without stray class cells".
    * v9: the convergence audit also screens the whole map (`RELOCALIZER_V9`: `RELOCALIZER_V7` with
      ``audit_screen=True``). Before it calls a belief converged, the audit looks for another place that
      explains the last 20 updates' scans as well; v8 searched only near its scan-proposal candidates
      and the particles, which can all lie 0.3-0.9 m and 0.2-0.5 rad from a look-alike place: too far
      for a window whose log-likelihood drops by tens of nats within 0.1 m. v9 also scores a grid of
      poses over the map's free space (0.3 m, 12 headings) with blurred fields and refines the best
      places; after a screen that found nothing, the audits of the next 100 updates search without it
      (``audit_screen_pause``). Fewer first convergences at a look-alike place (docs/relocalizer.md, "An
      audit that screens the whole map"); a screened audit costs about 11 ms more, so a short episode
      that ends at its first convergence costs about 0.6 ms more per step. The filter draws more random numbers in
      an audit, so episodes differ from v8's from the first audit on. Maps, worlds, sensors,
      observations, rewards and info keys are v8's (`SemRelocEnvV8` is v8).
    * v8: the map of ``map_source="mapping"`` (the default) or of another layout comes from the mapping run's version 3
      (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`): camera beams without a return no longer lower
      every class along the camera's range. The camera reads an object nearer than its 0.5 m minimum
      range as no return, so where the mapping drive passed that close to an object its beams had
      cleared the object's class cells and the space behind it: a cabinet against a wall could lose all
      of them (an outside trial: one of two translated halls lost its cabinet, and the belief converged
      in the other hall, 11 m away). The relocalizer, worlds, sensors, observations, rewards and info
      keys are v7's; only the filter's map differs (`SemRelocEnvV7` is v7). Other map sources
      (``"perfect"``, map files, GridMaps) give v7's episodes.
    * v7: the convergence audit searches harder and comes first (`RELOCALIZER_V7`:
      `RELOCALIZER_V6` with ``audit_places=16``, ``audited_convergence=True`` and
      ``audit_candidates_per_m2=14``). The audit refines
      the best-fitting poses of 16 different places on each side one by one before its
      coarse-to-fine search, so a look-alike place that explains the recent scans as well as the
      hypothesis is found more often; and a belief whose set comes to meet the "converged" criterion
      between two measurement updates (particles moved by a prediction alone) waits for the next
      update's audit before it is called converged (v6 called it converged at once, and audited it
      at the next update); and on maps larger than the lab the audit draws more candidates, 14 per
      m^2 of free space (2000 on any map before). Fewer first convergences at a look-alike place
      (docs/relocalizer.md, "Audit first, search wider"). The filter draws more random numbers in an audit, so episodes
      differ from v6's from the first audit on. Worlds, sensors, observations, rewards and info keys
      are v6's (`SemRelocEnvV6` is v6).
    * v6: a convergence holds (`RELOCALIZER_V6`: `RELOCALIZER_V5` with
      ``belief.converged_hold_weight=0.85`` and ``surprise_ratio=0.3``): once the belief is
      converged, it stays so while its heaviest hypothesis stays at the same place (within 1 m and
      45 deg of the one last called converged) with at least 85 % of the weight and the same spread
      limits; a new place must still reach 95 %. On v5 the flag flickered: the routine scan
      proposals take about 5 % of the mass at each update, so a belief at the truth hovered around
      the 95 % it needs, and about half the steps after a successful relocalization said "not
      converged". A *surprise* (once converged, an update whose scans fit the particles far worse
      than of late, as after a kidnapping) ends the hold and restarts the convergence audit's
      window, so a teleport is doubted sooner (docs/relocalizer.md, "Holding a convergence").
      For the same actions the particles are v5's up to the first surprise;
      ``info["belief"]["converged"]``, the ``wrong_convergence`` reward term and termination follow
      the held flag; ``info["mcl"]`` gains ``surprise`` (in every version; False where the test is
      off). An override lowering ``belief.converged_min_weight`` below 0.85, or choosing the
      ``spread`` rule, must set ``belief.converged_hold_weight`` too. Worlds, sensors, observations
      and rewards are otherwise v5's (`SemRelocEnvV5` is v5).
    * v5: the relocalizer audits each convergence (`RELOCALIZER_V5`: `RELOCALIZER_V4` with
      ``audit_window=20``): at the update where the belief would become converged, the pose
      outside its hypothesis that best explains the last 20 updates' scans is looked for, and if
      it fits within 1 nat (tempered) it is added as a second hypothesis, weighted by the
      likelihood ratio (at most as heavy as the first), so the belief is not converged. Fewer
      episodes whose belief first converges at a look-alike place (docs/relocalizer.md,
      "Convergence audit"). ``info["mcl"]``
      gains ``audit_log_ratio`` and ``n_audit_injected``. Worlds, sensors, observations, rewards
      and episode end are v4's (`SemRelocEnvV4` is v4).
    * v4: the relocalizer takes evidence from objects its map puts in the camera's view that the
      camera did not detect (`RELOCALIZER_V4`: `RELOCALIZER_V1` with ``negative_evidence``
      on). Up to 8 unlabelled camera returns per update are sampled along their rays; a pose from
      which the map puts an object on such a ray loses weight. Worlds, sensors, observations,
      rewards and episode end are v3's (`SemRelocEnvV3` is v3).
    * v3: ``layout="procedural_lookalike"`` layouts come from the procedural generator's version 2
      (`semreloc_env.layouts.PROCEDURAL_VERSION`): their corridor objects break the half turn that
      maps the rest of the layout onto itself by at least 1 m. In version 1 about a fifth of them
      did not (same-class objects on both end walls, for example), some by centimetres, where no
      motion can tell a pose from its half-turned image. Everything else is v2's, and so is every episode on another layout
      or on a lookalike seed whose layout passed the check (`SemRelocEnvV2` is v2).
    * v2: typed observations: the class labels are a ``MultiDiscrete`` entry ``semantic_class`` (int64)
      and the ranges a Box ``semantic_range``, replacing the float32 ``semantic`` Box that held both;
      ``info["mcl"]`` leaves out the diagnostics not computed in a step (v1: None), so vector envs
      batch them as float arrays. Dynamics, relocalizer, rewards and episode end are v1's: the same
      seed gives the same episode (`SemRelocEnvV1` is v1).
    * v1: the relocalizer of the relocalizer issue (`RELOCALIZER_V1`): particle count
      sized by the map's free area with KLD sampling, clustered resampling, scan-based
      (semantic) proposals with Mixture-MCL and augmented-MCL injection; ``converged`` needs
      one tight hypothesis with >= 95 % of the mass; ``pose_error`` is that of the heaviest
      hypothesis; ``info`` gains ``belief.hypotheses``, ``belief.estimate``, ``is_success`` and
      ``mcl.p_inject`` / ``mcl.lidar_used``; strict argument types and a ``CheckedReset``
      wrapper (see CHANGELOG.md). Layouts ``three_rooms`` and ``open_hall``.
    * v0: initial release (still registered, with the first release's relocalizer:
      `SemRelocEnvV0`). Over the first release it changed too: mapping-run map, reward
      term ``wrong_convergence``, tempering 0.03 (docs/paper004.md) — all before v1 existed.
    """

    _reset_option_keys = frozenset({"pose", "tracking", "kidnap_at_step", "kidnap_pose"})
    _world_option_keys = frozenset({"pose", "kidnap_pose"})
    default_relocalizer: MCLConfig = DEFAULT_RELOCALIZER
    """What ``relocalizer=None`` stands for and a dict of overrides applies to."""
    odometry_reads_slides = False
    """The simulated odometry reads what the wheels see, not a slide along a wall (`semreloc_env.sensors.Odometry`;
    True in v18 and older)."""
    odometry_exact_small_moves = True
    """The simulated odometry's default noise model moves a step under 1 cm in its own direction
    (`filters.motion.odometry.OdometryMotionConfig.exact_small_moves`; False in v21 and older)."""
    mapping_run_version: str = "6"
    """The mapping run (`semreloc_env.mapping_run.MAPPING_RUN_VERSIONS`) behind ``map_source="mapping"``
    and maps built from another layout."""

    def __init__(
        self,
        layout=None,
        layout_seed: int = 0,
        action_type: str = "discrete",
        robot=None,
        physics=None,
        lidar=None,
        camera=None,
        odometry=None,
        relocalizer: dict | MCLConfig | None = None,
        semantic: bool | None = None,
        map_source: str | Path | GridMap = "mapping",
        scenario: str = "nominal",
        reward_weights: dict | RewardWeights | None = None,
        render_mode: str | None = None,
    ):
        if scenario not in SCENARIOS:
            raise ValueError(f"unknown scenario {scenario!r}; choose one of {list(SCENARIOS)}")
        check_seed_use(layout, layout_seed, scenario)
        searched = searched_ros_map(map_source)
        if searched is not None:  # a ROS map named on the search path: as its path
            map_source = str(searched)
        named = isinstance(map_source, str) and (map_source in MAP_SOURCES or names_a_layout(map_source))
        if (
            not named
            and isinstance(map_source, (str, Path))
            and str(map_source)
            and Path(map_source).expanduser().is_dir()
        ):
            raise ValueError(
                f"map_source {str(map_source)!r} is a folder; give one map file in it (a ROS map .yaml/.yml with "
                "its image, or a layout file)"
            )
        if not (
            named or isinstance(map_source, (GridMap, Path)) or str(map_source).endswith((".yaml", ".yml", ".json"))
        ):
            raise ValueError(
                f"map_source must be one of {list(MAP_SOURCES)}, a map .yaml/.yml path, a GridMap, or a layout "
                f"(one of {list(LAYOUT_NAMES)}, a name on $SEMRELOC_LAYOUT_PATH or a layout file), got {map_source!r}"
            )
        if layout is None:  # unset: the world the map shows, or the lab
            layout = map_source if isinstance(map_source, GridMap) or is_ros_map_file(map_source) else "lab"
        super().__init__(layout, layout_seed, action_type, robot, physics, lidar, camera, odometry, render_mode)
        from ..config import coerce_config

        cfg = coerce_config(MCLConfig, relocalizer, "relocalizer", self.default_relocalizer)
        if semantic is not None and not isinstance(semantic, (bool, np.bool_)):
            raise ValueError(f"semantic must be True, False or None, got {type(semantic).__name__} {semantic!r:.60}")
        if semantic is not None:
            if isinstance(relocalizer, MCLConfig) or (isinstance(relocalizer, dict) and "use_semantic" in relocalizer):
                if bool(semantic) != cfg.use_semantic:
                    raise ValueError(f"semantic={semantic} contradicts relocalizer use_semantic={cfg.use_semantic}")
            cfg = dataclasses.replace(cfg, use_semantic=bool(semantic))
        self.mcl_config = cfg
        self.reward_weights = coerce_config(RewardWeights, reward_weights, "reward_weights")
        self.scenario = scenario
        self.map_source = map_source
        self.grid = maps_for(
            self.layout, map_source, self.lidar.params, self.camera.params, cfg.use_semantic, self.mapping_run_version
        )
        self._check_free(self.grid, self.layout, map_source)
        self._obstacles = changed_obstacles(self.layout, self.layout_seed) if scenario == "changed" else []
        self.mcl: MonteCarloLocalizer | None = None

    def _check_free(self, grid: GridMap, layout, map_source) -> None:
        """ValueError if ``grid`` has no free cell (the relocalizer would have nowhere to put particles)."""
        if grid.free_mask().any():
            return
        from_run = (
            isinstance(map_source, (str, Path)) and str(map_source) != "perfect" and not is_ros_map_file(map_source)
        )
        why = (
            f": a mapping run marks space free only along its lidar's beams (lidar range_max_m "
            f"{self.lidar.params.range_max_m} m)"
            if from_run
            else ""
        )
        raise ValueError(
            f"the map of layout {layout.name!r} has no free cell, so the relocalizer has nowhere to put particles{why}"
        )

    def set_layout(self, layout, layout_seed: int = 0, grid: GridMap | None = None, *, check_map: bool = True) -> None:
        """Use another layout from the next `reset` on (the running episode keeps its world).

        Args:
            layout: anything ``get_layout`` takes (name, path, dict, Layout).
            layout_seed: seeds procedural layouts and the ``"changed"`` scenario's obstacles.
            grid: the filter's map for it; None builds it from the env's ``map_source`` with
                `semreloc_env.maps.maps_for` (cached there).
            check_map: check that a given ``grid`` is a map of the layout (~5 ms); False for
                grids known to be, such as `maps_for`'s (as `RandomLayout` passes them).

        Raises:
            ValueError: ``grid`` is None and the env's map is a fixed file or GridMap (it belongs
                to one layout), or the grid's classes do not fit (`semreloc_env.maps.env_classes`), or it is not a map of the layout
                (`semreloc_env.map_world.check_map_matches_world`: another place, shifted or
                rotated), or it has no free cell; nothing changes then.
        """
        layout_seed = check_layout_seed(layout_seed)
        check_seed_use(layout, layout_seed, self.scenario)
        new_layout = get_layout(layout, seed=layout_seed, procedural_version=self.procedural_version)
        source = self.map_source if grid is None else None  # what the map comes from, for `_check_free`'s message
        if grid is None:
            if not (isinstance(self.map_source, str) and self.map_source in MAP_SOURCES):
                raise ValueError(
                    f"set_layout needs a grid: the env's map_source {self.map_source!r} is fixed to one layout"
                )
            grid = maps_for(
                new_layout, self.map_source, self.lidar.params, self.camera.params,
                mapping_version=self.mapping_run_version,
            )  # fmt: skip
        else:
            if not isinstance(grid, GridMap):
                raise ValueError(f"grid must be a GridMap or None, got {type(grid).__name__}")
            grid = env_classes(grid, "(the grid given to set_layout)", self.mcl_config.use_semantic)
            if check_map:  # ~5 ms
                check_map_matches_world(grid, new_layout)
        self._check_free(grid, new_layout, source)
        obstacles = changed_obstacles(new_layout, layout_seed) if self.scenario == "changed" else []
        self.layout, self.layout_seed, self.grid, self._obstacles = new_layout, layout_seed, grid, obstacles
        if self._renderer is not None:  # drawn for the old layout
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ hooks
    def _extra_obstacles(self) -> list:
        return self._obstacles

    def _validate_options(self, options: dict, world) -> None:
        tr = options.get("tracking")
        if tr is not None and not isinstance(tr, (bool, np.bool_)):
            raise ValueError(f"reset option tracking must be True, False or None, got {tr!r:.60}")
        k = options.get("kidnap_at_step")
        if k is not None and (not is_int(k) or k < 1):
            raise ValueError(f"kidnap_at_step must be an integer >= 1, got {k!r}")
        kp = options.get("kidnap_pose")
        if kp is not None and k is None:
            raise ValueError("kidnap_pose needs kidnap_at_step (the step at which to teleport)")
        if isinstance(kp, (str, bytes)):
            if kp != KIDNAP_TO_LOOKALIKE:  # bytes too: b"lookalike" is not the option's string
                raise ValueError(f"kidnap_pose must be a pose [x, y, theta] or {KIDNAP_TO_LOOKALIKE!r}, got {kp!r:.60}")
        elif kp is not None:
            kp = as_pose(kp, "kidnap_pose")
            reason = world.not_free_reason(kp[:2])
            if reason:
                raise ValueError(f"kidnap_pose {kp.tolist()} is not free: {reason}")
        if not self.grid.free_mask().any():
            raise ValueError("the relocalizer's map has no free cell: nowhere to put particles")

    def _reset_estimator(self, options: dict) -> None:
        self.mcl = MonteCarloLocalizer(self.grid, self.mcl_config, self._estimator_rng, measurement_model=cached_model(self.grid, self.mcl_config.lidar_field, self.mcl_config.semantic_field, self.mcl_config.backend, self.mcl_config.negative_evidence))  # fmt: skip
        if options.get("tracking"):
            self.mcl.init_around(self.world.pose, (0.1, 0.1, math.radians(5.0)))
        else:
            self.mcl.init_global()
        self._kidnap_at = options.get("kidnap_at_step")
        kp = options.get("kidnap_pose")  # the checked copy: the caller may change its array later
        self._kidnap_pose = None if kp is None else kp if isinstance(kp, str) else as_pose(kp, "kidnap_pose")
        self._kidnapped = False
        self._tracking = bool(options.get("tracking"))
        self._succeeded = False
        self._belief = None
        self._prev_entropy = None

    def _move(self, v, w):
        if self._kidnap_at is not None and self._steps + 1 == self._kidnap_at:
            drawn = self._start_rng.bit_generator.state
            try:
                target = self._kidnap_target()
            except BaseException:  # a failed search (or a Ctrl-C in it) leaves the draws as they were
                self._start_rng.bit_generator.state = drawn
                raise
            self.world.set_pose(target)
            self._kidnapped = True
            # the odometry must not see the jump: drive from the new pose, report that motion only
        return super()._move(v, w)

    def _kidnap_target(self) -> np.ndarray:
        """Where the kidnap step takes the robot: the reset's ``kidnap_pose``, a random free pose, or for
        ``"lookalike"`` the place that looks most like where it stands now (draws from the start generator)."""
        target = self._kidnap_pose
        if target is None:
            try:
                return self.world.sample_free_pose(self._start_rng)
            except ValueError:
                raise ValueError(
                    f"reset option kidnap_at_step={self._kidnap_at} (a random kidnap): layout "
                    f"{self.world.layout.name!r} has no free place to take the robot to; {_KIDNAP_FAILED}"
                ) from None
        if isinstance(target, str):  # KIDNAP_TO_LOOKALIKE
            try:
                return lookalike_kidnap(
                    self.world, self.world.pose, self._start_rng,
                    max_range_m=self.lidar.params.range_max_m, camera_range_m=self.camera.params.range_max_m,
                ).pose  # fmt: skip
            except NoPlaceError as e:
                raise NoPlaceError(
                    f"reset option kidnap_pose={KIDNAP_TO_LOOKALIKE!r} at step {self._kidnap_at}: {e}; {_KIDNAP_FAILED}"
                ) from None
        return target

    def _step_estimator(self, odom, lidar_scan, semantic_scan) -> None:
        self.mcl.predict(odom)
        self.mcl.update(lidar_scan, semantic_scan if self.mcl_config.use_semantic else None, force=self._steps == 0)
        self._prev_entropy = None if self._belief is None else self._belief.entropy_nats
        self._belief = self.mcl.belief()
        (mx, my, mth), (tx, ty, tth) = self._belief.estimate.tolist(), self.world.pose.tolist()
        self._error = {
            "position": float(np.hypot(mx - tx, my - ty)),  # NumPy's hypot: Python's math rounds differently
            "heading": abs(wrap_float(mth - tth)),
        }

    @property
    def belief(self):
        """The filter's summary after the last reset or step (`filters.localization.belief.Belief`),
        the same object ``info["belief"]`` is made from (None before the first reset); never the true pose."""
        return getattr(self, "_belief", None)

    def pose_error(self) -> dict[str, float]:
        """Position (m) and heading (rad) error of the belief's estimate (its heaviest hypothesis)
        against the true pose (this step)."""
        return dict(self._error)

    def _near_truth(self) -> bool:
        """The belief's estimate is within 0.5 m and 15 deg of the true pose."""
        return self._error["position"] < SUCCESS_POSITION_M and self._error["heading"] < SUCCESS_HEADING_RAD

    def _is_success(self) -> bool:
        """Relocalized: the belief converged at the truth, in a global or post-kidnap episode."""
        if self._tracking and not self._kidnapped:
            return False
        return bool(self._belief.converged and self._near_truth())

    def _reward_terms(self, collided: bool) -> dict[str, float]:
        w = self.reward_weights
        drop = 0.0 if self._prev_entropy is None else self._prev_entropy - self._belief.entropy_nats
        success = self._is_success() and not self._succeeded
        self._succeeded |= success
        wrong = self._belief.converged and not self._near_truth()
        return {
            "time": w.time,
            "collision": w.collision if collided else 0.0,
            "entropy": w.entropy * drop,
            "success": w.success if success else 0.0,
            "wrong_convergence": w.wrong_convergence if wrong else 0.0,
        }

    def _terminated(self) -> bool:
        return self._succeeded

    def _info(self) -> dict[str, Any]:
        info = super()._info()
        info["belief"] = self._belief.as_dict()
        info["pose_error"] = self.pose_error()
        # NaN marks "not computed this step" in the diagnostics; None compares equal to itself
        info["mcl"] = self.mcl.last_diagnostics.as_dict()
        for k, v in list(info["mcl"].items()):  # NaN marks "not computed this step"
            if isinstance(v, float) and math.isnan(v):
                if self.info_missing == "drop":
                    del info["mcl"][k]
                else:
                    info["mcl"][k] = None
        info["kidnapped"] = self._kidnapped
        info["is_success"] = self._succeeded
        return info

    def _render_state(self) -> dict[str, Any]:
        state = super()._render_state()
        state["particles"] = self.mcl.poses
        state["estimate"] = self._belief.estimate
        err = self.pose_error()
        hyp = _belief_title(self._belief)
        state["title"] = (
            f"{self.world.layout.name}  step {self._steps}  error {err['position']:.2f} m / {math.degrees(err['heading']):.0f} deg"
            f"{hyp}  {'converged' if self._belief.converged else ''}"
        )
        return state


_KIDNAP_FAILED = (
    "the step changed nothing, and every step raises so until a reset (with another kidnap option, or none)"
)

SPREAD_TITLE_STD_M = 1.0
"""A heaviest hypothesis at least this wide (position std, m) is titled as a spread belief, not a hypothesis."""


def _belief_title(belief) -> str:
    """The belief's part of a frame's title: the heaviest hypothesis and its weight, or, while that
    hypothesis is at least `SPREAD_TITLE_STD_M` wide (a uniform cloud is one connected cluster), the spread."""
    best = belief.best
    if best is None:
        return ""
    if best.pos_std_m >= SPREAD_TITLE_STD_M:
        return (
            f"  belief spread (std {best.pos_std_m:.1f} m, {belief.n_clusters} cluster{'s' * (belief.n_clusters != 1)})"
        )
    return f"  best hypothesis {100 * best.weight:.0f} % (std {best.pos_std_m:.1f} m)"


class SemRelocEnvV21(SemRelocEnv):
    """``SemReloc-v21``: `SemRelocEnv` with the relocalizer of v21 (`RELOCALIZER_V21`: a step under 1 cm goes along the
    heading, KLD's retry draws a second sequence) and its simulated odometry, which reads a step under 1 cm along the
    heading too. Otherwise identical to ``SemReloc-v22``. Kept so that results made with v21 can be reproduced; new
    work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V21
    odometry_exact_small_moves = False


class SemRelocEnvV20(SemRelocEnvV21):
    """``SemReloc-v20``: `SemRelocEnv` with the relocalizer of v20 (`RELOCALIZER_V20`: a global start draws 50
    particles per m^2, a still step draws its zero motion noise). Otherwise identical to ``SemReloc-v21``. Kept so
    that results made with v20 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V20


class SemRelocEnvV19(SemRelocEnvV20):
    """``SemReloc-v19``: `SemRelocEnv` with the relocalizer of v19 (`RELOCALIZER_V19`: between updates the belief is
    the moved particle set summarised again). Otherwise identical to ``SemReloc-v20``. Kept so that results made with
    v19 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V19


class SemRelocEnvV18(SemRelocEnvV19):
    """``SemReloc-v18``: `SemRelocEnv` with the relocalizer of v18 (`RELOCALIZER_V18`: KLD's ``kld_epsilon`` 0.05, the
    remembered places stay where the last update left them) and odometry that reads the true increment, a slide
    along a wall included. Otherwise identical to ``SemReloc-v19``. Kept so that results made with v18 can be
    reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V18
    odometry_reads_slides = True


class SemRelocEnvV17(SemRelocEnvV18):
    """``SemReloc-v17``: `SemRelocEnv` with the relocalizer of v17 (`RELOCALIZER_V17`: the audit a hold lost without a
    surprise turns on judges the last 20 updates' scans at once). Otherwise identical to ``SemReloc-v18``. Kept so
    that results made with v17 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V17


class SemRelocEnvV16(SemRelocEnvV17):
    """``SemReloc-v16``: `SemRelocEnv` with the relocalizer of v16 (`RELOCALIZER_V16`: a tracking start holds no
    pose, and its surprise tests are armed only once the belief has met the 95 % rule). Otherwise identical to
    ``SemReloc-v17``. Kept so that results made with v16 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V16


class SemRelocEnvV15(SemRelocEnvV16):
    """``SemReloc-v15``: `SemRelocEnv` with the relocalizer of v15 (`RELOCALIZER_V15`: a held convergence that ends
    without a surprise leaves the audit off in a tracking episode). Otherwise identical to ``SemReloc-v16``. Kept so
    that results made with v15 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V15


class SemRelocEnvV14(SemRelocEnvV15):
    """``SemReloc-v14``: `SemRelocEnv` with the relocalizer of v14 (`RELOCALIZER_V14`: the audit a surprise turns on
    in a tracking episode stays on until the next reset). Otherwise identical to ``SemReloc-v15``. Kept so that
    results made with v14 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V14


class SemRelocEnvV13(SemRelocEnvV14):
    """``SemReloc-v13``: `SemRelocEnv` with the relocalizer of v13 (`RELOCALIZER_V13`: no surprise test of the
    camera's own). Otherwise identical to ``SemReloc-v14``. Kept so that results made with v13 can be reproduced;
    new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V13


class SemRelocEnvV12(SemRelocEnvV13):
    """``SemReloc-v12``: `SemRelocEnv` with the relocalizer of v12 (`RELOCALIZER_V12`: its surprise test compares
    with augmented MCL's fast average, which injections restart). Otherwise identical to ``SemReloc-v13``. Kept
    so that results made with v12 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V12


class SemRelocEnvV11(SemRelocEnvV12):
    """``SemReloc-v11``: `SemRelocEnvV12` with the maps of the mapping run's version 5 (a drive that skips passages
    between its lattice's rows and columns) and the relocalizer of v10 and v11 (`RELOCALIZER_V10`: no audit in
    a tracking episode, also after a surprise). Otherwise identical to ``SemReloc-v12``. Kept so that results
    made with v11 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V10
    mapping_run_version = "5"


class SemRelocEnvV10(SemRelocEnvV11):
    """``SemReloc-v10``: `SemRelocEnvV11` with the maps of the mapping run's version 4 (space the lidar's returns
    did not reach left unknown). Otherwise identical to ``SemReloc-v11``. Kept so that results made with v10
    can be reproduced; new work should use ``SemReloc-v22``."""

    mapping_run_version = "4"


class SemRelocEnvV9(SemRelocEnvV10):
    """``SemReloc-v9``: `SemRelocEnvV10` with the maps of the mapping run's version 3 (stray class cells kept)
    and the relocalizer of v9 (`RELOCALIZER_V9`: the screen's pause ignores where the belief is). Otherwise
    identical to ``SemReloc-v10``. Kept so that results made with v9 can be reproduced; new work should use
    ``SemReloc-v21``."""

    default_relocalizer = RELOCALIZER_V9
    mapping_run_version = "3"


class SemRelocEnvV8(SemRelocEnvV9):
    """``SemReloc-v8``: `SemRelocEnvV9` with the relocalizer of v7 and v8 (`RELOCALIZER_V7`: the convergence
    audit searches near its candidates and the particles only). Otherwise identical to ``SemReloc-v9``.
    Kept so that results made with v8 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V7


class SemRelocEnvV7(SemRelocEnvV8):
    """``SemReloc-v7``: `SemRelocEnvV8` with the maps of the mapping run's version 2, whose camera beams
    without a return (objects nearer than the camera's minimum range among them) cleared the classes along
    the camera's range. Otherwise identical to ``SemReloc-v8``. Kept so that results made with v7 can be
    reproduced; new work should use ``SemReloc-v22``."""

    mapping_run_version = "2"


class SemRelocEnvV6(SemRelocEnvV7):
    """``SemReloc-v6``: `SemRelocEnvV7` with the relocalizer of v6 (`RELOCALIZER_V6`: the convergence audit's
    coarse-to-fine search only, and a convergence reached between updates called at once). Otherwise
    identical to ``SemReloc-v7``. Kept so that results made with v6 can be reproduced; new work should use
    ``SemReloc-v21``."""

    default_relocalizer = RELOCALIZER_V6


class SemRelocEnvV5(SemRelocEnvV6):
    """``SemReloc-v5``: `SemRelocEnvV6` with the relocalizer of v5 (`RELOCALIZER_V5`: a convergence is
    judged afresh at every step, no hold and no surprise test). Otherwise identical to ``SemReloc-v6``. Kept so that
    results made with v5 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V5


class SemRelocEnvV4(SemRelocEnvV5):
    """``SemReloc-v4``: `SemRelocEnvV5` with the relocalizer of v4 (`RELOCALIZER_V4`: no convergence
    audit). Otherwise identical to ``SemReloc-v5``. Kept so that results made with v4 can be
    reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V4


class SemRelocEnvV3(SemRelocEnvV4):
    """``SemReloc-v3``: `SemRelocEnvV4` with the relocalizer of v1-v3 (`RELOCALIZER_V1`: no evidence
    from objects not seen). Otherwise identical to ``SemReloc-v4``. Kept so that results made with
    v3 can be reproduced; new work should use ``SemReloc-v22``."""

    default_relocalizer = RELOCALIZER_V1


class SemRelocEnvV2(SemRelocEnvV3):
    """``SemReloc-v2``: `SemRelocEnvV3` with lookalike layouts from the procedural generator's version 1
    (no check that their corridor objects break the half turn). Otherwise identical to ``SemReloc-v3``.
    Kept so that results made with v2 can be reproduced; new work should use ``SemReloc-v22``."""

    procedural_version = 1


class SemRelocEnvV1(SemRelocEnvV2):
    """``SemReloc-v1``: `SemRelocEnvV2` with the flat observation (one float32 ``semantic`` Box:
    ranges, then the labels as floats) and None in ``info["mcl"]`` for values not computed in a step.
    Otherwise identical to ``SemReloc-v2`` (same seed, same episode). Kept so that policies trained on
    v1 keep working; new work should use ``SemReloc-v22``."""

    observation_layout = "flat"
    info_missing = "none"


class SemRelocEnvV0(SemRelocEnvV1):
    """``SemReloc-v0``: `SemRelocEnvV1` with the first release's relocalizer
    (`LEGACY_RELOCALIZER`). Kept so that results made with v0 can be reproduced; use ``SemReloc-v21``."""

    default_relocalizer = LEGACY_RELOCALIZER
