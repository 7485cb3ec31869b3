"""``SemSlam-v2`` (and ``-v1``, ``-v0``): landmark SLAM (FastSLAM + WOC, paper 000) on the semantic camera's object detections."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, ClassVar

import numpy as np

from filters.motion.odometry import OdometryMotionConfig
from filters.motion.odometry_slam import OdometryIncrementModel
from filters.numbers import is_int
from filters.pose import wrap_angle
from filters.slam.association import AssociationConfig
from filters.slam.class_votes import ClassVotingFastSLAM
from filters.slam.fastslam import FastSLAMConfig, SLAMEstimate
from filters.slam.landmarks import RangeBearingNoise
from filters.slam.metrics import true_landmark_errors
from filters.slam.weight_transforms import WOC
from filters.smc.resampling import effective_sample_size

from ..config import check_reward_weights, coerce_config
from ..landmark_sensor import LandmarkSensor, LandmarkSensorParams
from ..layouts import CLASS_NAMES
from .base import SemRelocBase, check_seed_use

DEFAULT_OBS_NOISE = RangeBearingNoise(sigma_r_m=0.15, sigma_b_rad=0.05)
"""The filter's range-bearing noise: about 1.1x / 1.6x the spread of the default landmark sensor's
observations around the true object centres on the lab (0.13 m, 0.03 rad; see docs/semslam.md)."""


@dataclasses.dataclass(frozen=True)
class SlamParams:
    """Settings of the WOCPF SLAM filter (FastSLAM + WOC weight step, paper 000).

    Attributes:
        n_particles: particles, ``1 <= N <= 100,000`` (each carries its own landmark map).
        version: FastSLAM 1 or 2 (2: Gaussian proposal refined by the observations, the paper's step 4).
        woc_k: WOC scaling factor ``K`` of paper 000 Eq. 7, ``1 <= K <= inf`` (``inf``: plain FastSLAM).
            The paper does not state its K; 2.0 is this env's choice.
        known_association: True: observations carry the true object index (landmark id = object index;
            detections on no object, i.e. false positives, are then dropped). False (default): maximum
            likelihood association with the NIS gates below.
        gate_associate, gate_new: NIS gates of `filters.slam.association.AssociationConfig`.
        gate_first: choose the ML match among the landmarks inside the gate (`AssociationConfig.gate_first`;
            the dataclass's default False is ``SemSlam-v1``'s and ``-v0``'s, `SemSlamEnv.default_slam` True is
            ``SemSlam-v2``'s).
        resampler: resampling scheme name (`filters.smc.resampling.get_resampler`).
        resample_ess_fraction: resample when the ESS of the WOC weights falls below this fraction of N
            (1.0: after every update with observations, as the paper does).
        motion_noise: dict of `filters.motion.odometry.OdometryMotionConfig` overrides for the filter's
            odometry noise; ``None`` (default) uses the simulator's ``odometry`` noise (a matched model).
    """

    n_particles: int = 100
    version: int = 2
    woc_k: float = 2.0
    known_association: bool = False
    gate_associate: float = 9.21
    gate_new: float = 25.0
    gate_first: bool = False
    resampler: str = "systematic"
    resample_ess_fraction: float = 1.0
    motion_noise: dict | OdometryMotionConfig | None = None
    _allow_inf: ClassVar[frozenset] = frozenset({"woc_k"})  # K = inf is plain FastSLAM

    def __post_init__(self) -> None:
        if not isinstance(self.known_association, (bool, np.bool_)):
            raise ValueError(f"slam.known_association must be a bool, got {self.known_association!r}")
        if not (isinstance(self.woc_k, (int, float)) and float(self.woc_k) >= 1.0):
            raise ValueError(f"slam.woc_k must be a number with 1 <= K <= inf, got {self.woc_k!r}")
        n = self.n_particles
        if not (is_int(n) and 1 <= n <= 100_000):
            # each FastSLAM particle carries its own landmark map
            raise ValueError(f"slam.n_particles must be an int in [1, 100,000], got {n!r}")

    def fastslam_config(self) -> FastSLAMConfig:
        """The `FastSLAMConfig` these settings stand for (ValueError if invalid)."""
        assoc = AssociationConfig(
            mode="known" if self.known_association else "ml",
            gate_associate=float(self.gate_associate),
            gate_new=float(self.gate_new),
            gate_first=self.gate_first,
        )
        return FastSLAMConfig(
            n_particles=self.n_particles,
            version=self.version,
            association=assoc,
            resampler=self.resampler,
            resample_ess_fraction=self.resample_ess_fraction,
            weight_transform=WOC(float(self.woc_k)),
        )


@dataclasses.dataclass(frozen=True)
class SlamRewardWeights:
    """Weights of the reward terms (see the env docstring)."""

    time: float = -0.01
    collision: float = -0.5
    pose_error: float = -0.1
    discovery: float = 0.1

    def __post_init__(self) -> None:
        check_reward_weights(self)


class SemSlamEnv(SemRelocBase):
    """Landmark SLAM of a differential-drive robot from semantic object detections.

    ## Description
    The world, robot and sensors of ``SemReloc-v22`` (a pymunk world built from a *layout*, a 360 deg
    lidar, a forward semantic camera, wheel odometry that reads what the wheels see, no slide along a wall, and moves
    a step under 1 cm in its own direction). Inside the env runs **WOCPF SLAM** (paper 000):
    FastSLAM (`filters.slam.fastslam.FastSLAM`, version 2 by default) whose importance weights go
    through the WOC step ``psi = (K-1)/K w + mean(w)/K`` before resampling. Its controls are the noisy
    odometry increments (`filters.motion.odometry_slam.OdometryIncrementModel`); its observations
    are range-bearing *landmarks*: each object the semantic camera labels is one observation to a point
    near the object's centre (`semreloc_env.landmark_sensor`). Landmarks also collect class votes
    (`filters.slam.class_votes.ClassVotingFastSLAM`), so the map is semantic. No map is given:
    the policy should drive so that the robot sees many objects and its pose stays well estimated.

    ## Action Space
    ``action_type="discrete"`` (default): ``Discrete(4)`` -- 0 forward at ``robot.max_linear_mps``,
    1 turn left, 2 turn right (at ``robot.max_angular_rps``), 3 stop.
    ``action_type="continuous"``: ``Box(-1, 1, (2,))`` -- ``(v, omega)`` scaled by the same maxima.
    An invalid action (out of range, NaN, the wrong shape or kind) raises ``ValueError`` and changes nothing.
    Continuous actions are checked by value, not dtype: any two finite real numbers (not bools) in ``[-1, 1]``
    are taken, int64 and float64 arrays included, which Gymnasium's ``Box.contains`` refuses; values within
    ``semreloc_env.envs.spaces.ACTION_BOUND_SLACK`` (1e-5) of a bound are clipped to it.

    ## Observation Space
    Identical to ``SemReloc-v2``: a ``Dict`` of float32 boxes and one ``MultiDiscrete``.

    | key | space | shape | range | meaning |
    |---|---|---|---|---|
    | ``lidar`` | Box float32 | ``(lidar.n_beams,)`` | ``[0, range_max_m]`` m | ranges, evenly spaced over ``fov_rad`` from ``-fov/2``; no return reads ``range_max_m`` |
    | ``odometry`` | Box float32 | ``(3,)`` | ``+-(1 m, 1 m, pi)`` | noisy increment ``(dx, dy, dtheta)`` since the last step, in the previous robot frame |
    | ``semantic_class`` | MultiDiscrete int64 | ``(camera.n_beams,)`` | ``{0..4}`` | class label per pseudo-laser beam (0 none, 1 door, 2 chair, 3 trash_bin, 4 cabinet) |
    | ``semantic_range`` | Box float32 | ``(camera.n_beams,)`` | ``[0, camera.range_max_m]`` m | pseudo-laser range per beam |

    ``SemSlam-v0`` has ``SemReloc-v1``'s flat layout instead: one float32 Box ``semantic`` of shape
    ``(2 * camera.n_beams,)``, the ranges, then the labels as floats.

    ## Rewards
    A dict of named terms in ``info["rewards"]``, weighted by ``reward_weights``
    (`SlamRewardWeights`); the reward is their sum: ``time`` (constant per step),
    ``collision`` (robot touched an obstacle), ``pose_error`` (weight times the SLAM position error in m,
    so negative by default), ``discovery`` (weight times the number of objects observed for the first time
    in this step).

    ## Starting State
    A uniformly random free pose, or ``options={"pose": (x, y, theta)}``. The filter starts with every
    particle at the true start pose, zero uncertainty and an empty map: SLAM's own frame has its origin at
    the true start pose, and its estimates are reported in world coordinates (that frame placed at the
    true start pose), so they compare directly with the truth. The reset step already observes.

    ## Episode End
    Never terminated by the env. Truncated by the time limit (``max_episode_steps``, 400 at registration).

    ## Info
    * ``pose``: true pose ``[x m, y m, theta rad]`` (ndarray).
    * ``slam``: the filter's estimate, plain Python lists: ``pose`` ``[x, y, theta]`` (weighted mean,
      circular mean for theta), ``pose_cov`` 3x3, ``landmarks`` ``M x [x, y]`` m and ``landmark_covs``
      ``M x 2 x 2`` m^2 (the highest-weight particle's map), ``landmark_ids`` (object index under known
      association, slot index otherwise), ``landmark_classes`` (most voted label 1..4), ``n_landmarks`` M,
      ``n_observations`` K of this step, ``ess`` of the last update's weights.
    * ``slam_error``: ``position`` m and ``heading`` rad of ``slam.pose``; ``landmark`` m: mean over the
      true objects observed so far of the distance from the object's centroid to its estimated landmark
      (known association: the landmark with the object's id; ML association: the nearest estimated
      landmark), left out while no object has been observed (``SemSlam-v0``: None); ``n_seen`` objects
      observed so far.
    * ``rewards``; ``collided`` (step only).

    ## Arguments
    * ``layout``, ``layout_seed``, ``action_type``, ``robot``, ``physics``, ``lidar``, ``camera``,
      ``odometry``, ``render_mode``: as in ``SemReloc-v22`` (``odometry``: a dict of overrides keeps
      ``exact_small_moves`` True; an ``OdometryMotionConfig`` instance replaces the noise whole).
    * ``slam``: dict of overrides of `default_slam` (``n_particles`` 100, ``version`` 2, ``woc_k`` 2.0,
      ``known_association`` False, ``gate_first`` True, gates, resampler, ``motion_noise``); a `SlamParams` instance
      replaces it whole (its own ``gate_first``, False unless given: ``dataclasses.replace(SemSlamEnv.default_slam,
      ...)`` keeps v2's).
    * ``obs_noise``: dict of overrides of the filter's `filters.slam.landmarks.RangeBearingNoise`
      (``sigma_r_m`` 0.15, ``sigma_b_rad`` 0.05).
    * ``landmark_sensor``: dict of overrides of `semreloc_env.landmark_sensor.LandmarkSensorParams`.
    * ``reward_weights``: dict of overrides of `SlamRewardWeights`.
    Unknown arguments or keys raise ``TypeError`` / ``ValueError``.

    ## Reset options
    ``pose`` only; anything else raises ``ValueError`` and leaves the episode as it was
    (checked outside the time limit, see `semreloc_env.wrappers.CheckedReset`).

    ## Version History
    * v2: the odometry of ``SemReloc-v22``: it reads what a differential drive's wheels see, no slide along a wall
      (``SemReloc-v19``'s), and moves a step under 1 cm in its own direction, in the simulated odometry and in the
      SLAM motion model (``SemReloc-v22``'s); and maximum-likelihood association chooses among the landmarks inside
      the gate (``slam.gate_first``, `default_slam`). v1 read a 2.8 cm slide along a wall as a sideways step with
      18 deg of heading noise, took a 5 mm reverse (and a turn's small noisy translation) as a step forwards, and let
      a tight landmark outside the gate beat the ones inside it (docs/semslam.md, "SemSlam-v2").
    * v1: typed observations as in ``SemReloc-v2`` (``semantic_class`` MultiDiscrete and ``semantic_range``
      Box instead of the float32 ``semantic`` Box); ``info["slam_error"]`` leaves ``landmark`` out while no
      object has been observed (v0: None). Dynamics, filter and rewards unchanged (`SemSlamEnvV0` is v0).
    * v0: initial release.
    """

    _reset_option_keys = frozenset({"pose"})
    odometry_reads_slides = False
    """The simulated odometry reads what the wheels see, not a slide along a wall (`semreloc_env.sensors.Odometry`;
    True in v1 and v0)."""
    odometry_exact_small_moves = True
    """A step under 1 cm moves in its own direction, in the simulated odometry and (through its noise config) the SLAM
    motion model (False in v1 and v0)."""
    default_slam: ClassVar[SlamParams] = SlamParams(gate_first=True)
    """What ``slam=None`` stands for and a dict of overrides applies to (``gate_first`` False in v1 and v0)."""
    procedural_version = 1
    """Lookalike layouts by name as ``SemReloc-v2`` draws them (the SLAM episode starts from a known pose,
    so their half-turn symmetry does not matter here; pass a Layout from
    ``get_layout("procedural_lookalike", seed)`` for ``SemReloc-v3``'s and ``-v4``'s)."""

    def __init__(
        self,
        layout="lab",
        layout_seed: int = 0,
        action_type: str = "discrete",
        robot=None,
        physics=None,
        lidar=None,
        camera=None,
        odometry=None,
        slam: dict | SlamParams | None = None,
        obs_noise: dict | RangeBearingNoise | None = None,
        landmark_sensor: dict | LandmarkSensorParams | None = None,
        reward_weights: dict | SlamRewardWeights | None = None,
        render_mode: str | None = None,
    ):
        check_seed_use(layout, layout_seed, "nominal")
        super().__init__(layout, layout_seed, action_type, robot, physics, lidar, camera, odometry, render_mode)
        self.slam_params = coerce_config(SlamParams, slam, "slam", self.default_slam)
        self.fastslam_config = self.slam_params.fastslam_config()
        motion = self.slam_params.motion_noise
        if not isinstance(motion, OdometryMotionConfig):
            motion = coerce_config(OdometryMotionConfig, motion, "slam.motion_noise", self.odometry.params)
        self.motion_model = OdometryIncrementModel(motion)
        self.obs_noise = coerce_config(RangeBearingNoise, obs_noise, "obs_noise", DEFAULT_OBS_NOISE)
        self.landmark_sensor = LandmarkSensor(
            self.camera, coerce_config(LandmarkSensorParams, landmark_sensor, "landmark_sensor")
        )
        self.reward_weights = coerce_config(SlamRewardWeights, reward_weights, "reward_weights")
        self.centroids = np.array([o.centroid() for o in self.layout.objects]).reshape(-1, 2)
        self.slam: ClassVotingFastSLAM | None = None

    # ------------------------------------------------------------------ hooks
    def _reset_estimator(self, options: dict) -> None:
        self.slam = ClassVotingFastSLAM(
            self.motion_model,
            self.obs_noise,
            self.fastslam_config,
            self._estimator_rng,
            initial_pose=self.world.pose,
            n_classes=len(CLASS_NAMES),
        )
        self._seen = np.zeros(len(self.layout.objects), dtype=bool)
        self._n_new_seen = 0
        self._n_obs = 0
        self._estimate: SLAMEstimate | None = None

    def _step_estimator(self, odom, lidar_scan, semantic_scan) -> None:
        self.slam.predict(odom, self.physics_params.dt_s)
        z, classes, true_ids = self.landmark_sensor.read(self.world, self.world.pose, semantic_scan)
        if self.slam_params.known_association:
            keep = true_ids >= 0  # false positives have no id to give
            z, classes, true_ids = z[keep], classes[keep], true_ids[keep]
        self.slam.update(z, true_ids if self.slam_params.known_association else None, classes)
        seen = true_ids[true_ids >= 0]
        self._n_new_seen = int(np.count_nonzero(~self._seen[np.unique(seen)]))
        self._seen[seen] = True
        self._n_obs = int(z.shape[0])
        self._estimate = self.slam.estimate()

    def slam_error(self) -> dict[str, Any]:
        """Pose error (m, rad) of the estimate and the mean landmark error (m) over the objects seen so far."""
        est, truth = self._estimate, self.world.pose
        seen = np.flatnonzero(self._seen)
        lm_err = None
        if seen.size:
            d = true_landmark_errors(
                est.landmarks, est.landmark_ids, self.centroids, seen, self.slam_params.known_association
            )
            lm_err = float(np.mean(d))
        return {
            "position": float(np.hypot(*(est.pose[:2] - truth[:2]))),
            "heading": float(abs(wrap_angle(est.pose[2] - truth[2]))),
            "landmark": lm_err,
            "n_seen": int(seen.size),
        }

    def _reward_terms(self, collided: bool) -> dict[str, float]:
        w = self.reward_weights
        return {
            "time": w.time,
            "collision": w.collision if collided else 0.0,
            "pose_error": w.pose_error * self.slam_error()["position"],
            "discovery": w.discovery * self._n_new_seen,
        }

    def _landmark_classes(self) -> np.ndarray:
        return self.slam.landmark_classes(self._estimate.landmark_ids)

    def _info(self) -> dict[str, Any]:
        info = super()._info()
        est = self._estimate
        info["slam"] = {
            "pose": [float(v) for v in est.pose],
            "pose_cov": est.pose_cov.astype(float).tolist(),
            "landmarks": est.landmarks.astype(float).tolist(),
            "landmark_covs": est.landmark_covs.astype(float).tolist(),
            "landmark_ids": [int(i) for i in est.landmark_ids],
            "landmark_classes": [int(c) for c in self._landmark_classes()],
            "n_landmarks": est.count,
            "n_observations": self._n_obs,
            "ess": effective_sample_size(self.slam.last_weights),
        }
        info["slam_error"] = self.slam_error()
        if info["slam_error"]["landmark"] is None and self.info_missing == "drop":
            del info["slam_error"]["landmark"]
        return info

    def _render_state(self) -> dict[str, Any]:
        state = super()._render_state()
        est = self._estimate
        state["particles"] = self.slam.poses
        state["estimate"] = est.pose
        state["landmarks"] = {"means": est.landmarks, "classes": self._landmark_classes()}
        err = self.slam_error()
        lm = "-" if err["landmark"] is None else f"{err['landmark']:.2f} m"
        state["title"] = (
            f"{self.world.layout.name}  step {self._steps}  pose error {err['position']:.2f} m / "
            f"{math.degrees(err['heading']):.0f} deg  landmarks {est.count} (seen {err['n_seen']}, error {lm})"
        )
        return state


class SemSlamEnvV1(SemSlamEnv):
    """``SemSlam-v1``: `SemSlamEnv` with the odometry of ``SemReloc-v18`` (it reads the true increment, a slide along a
    wall included, and takes a step under 1 cm along the heading, in the simulator and the SLAM motion model) and
    maximum-likelihood association that picks the best landmark before gating (``slam.gate_first`` False). Otherwise
    identical to ``SemSlam-v2``. Kept so that results made with v1 can be reproduced; new work should use
    ``SemSlam-v2``."""

    odometry_reads_slides = True
    odometry_exact_small_moves = False
    default_slam = SlamParams()


class SemSlamEnvV0(SemSlamEnvV1):
    """``SemSlam-v0``: `SemSlamEnvV1` with the flat observation (one float32 ``semantic`` Box) and
    ``info["slam_error"]["landmark"] = None`` before the first object is seen. Otherwise identical to
    ``SemSlam-v1`` (same seed, same episode); new work should use ``SemSlam-v2``."""

    observation_layout = "flat"
    info_missing = "none"
