"""SemSlam-v2 (and v1, v0): env checks, determinism, landmark sensor, odometry motion model, zero-noise SLAM, bad
input."""

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from helpers import assert_identical, random_rollout
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import semreloc_env  # noqa: F401  (registers the ids)
from agents.baselines import WallFollowExplorer
from filters.motion.odometry import OdometryMotionConfig
from filters.motion.odometry_slam import OdometryIncrementModel
from filters.motion.velocity import MotionModel
from filters.pose import compose, wrap_angle
from filters.robot_data.scans import SemanticScan
from filters.slam.class_votes import ClassVotingFastSLAM
from filters.slam.fastslam import FastSLAMConfig
from filters.slam.landmarks import RangeBearingNoise
from semreloc_env.config import CameraParams
from semreloc_env.landmark_sensor import LandmarkSensor, LandmarkSensorParams, extract_landmarks
from semreloc_env.sensors import SemanticCamera
from semreloc_env.world import build_world

FAST = {"slam": {"n_particles": 20}}
PERFECT_CAMERA = {"noise_std_m": 0.0, "miss_rate": 0.0, "wrong_class_rate": 0.0, "false_positive_rate": 0.0}
NO_ODOM_NOISE = {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0}
DISC_R = 0.25


def make(**kw):
    return gym.make("SemSlam-v2", **{**FAST, **kw})


def _disc(cls, cx, cy, r=DISC_R, n=24):
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return {"class": cls, "polygon": np.stack([cx + r * np.cos(a), cy + r * np.sin(a)], 1).tolist()}


# a 6 m x 4 m room with four near-circular objects: their centre is the surface point + radius along the ray
DISC_ROOM = {
    "name": "disc_room",
    "outer": [[0, 0], [6, 0], [6, 4], [0, 4]],
    "objects": [
        _disc("chair", 2.0, 1.0),
        _disc("trash_bin", 4.5, 3.0),
        _disc("cabinet", 4.0, 1.0),
        _disc("door", 1.5, 3.0),
    ],
}


# ---------------------------------------------------------------- env checks
def test_check_env_gymnasium_and_sb3_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for action_type in ("discrete", "continuous"):
            env = make(action_type=action_type)
            gym_check_env(env.unwrapped, skip_render_check=True)
            sb3_check_env(env.unwrapped, warn=True)
            env.close()


def test_two_envs_same_seed_same_actions_are_identical_for_200_steps():
    kw = {"layout": "twin_rooms", "slam": {"n_particles": 30}}
    a = random_rollout(make(**kw), seed=3)
    b = random_rollout(make(**kw), seed=3)
    assert_identical(a, b)
    assert max(step[-1]["slam"]["n_landmarks"] for step in a[1:]) > 0  # the filter did map something
    c = random_rollout(make(**kw), seed=4, n=3)
    assert not np.array_equal(a[0][0]["lidar"], c[0][0]["lidar"])


def test_info_rewards_and_time_limit():
    env = make(layout="twin_rooms")
    obs, info = env.reset(seed=0)
    assert set(info) >= {"pose", "slam", "slam_error"}
    np.testing.assert_allclose(info["slam"]["pose"], info["pose"], atol=1e-12)  # starts at the true pose
    policy = WallFollowExplorer()
    steps = 0
    while True:
        obs, r, term, trunc, info = env.step(policy(obs))
        steps += 1
        assert not term
        assert env.observation_space.contains(obs)
        s = info["slam"]
        m = s["n_landmarks"]
        assert np.shape(s["landmarks"]) == (m, 2) or m == 0
        assert np.shape(s["landmark_covs"]) == (m, 2, 2) or m == 0
        assert len(s["landmark_classes"]) == m and set(s["landmark_classes"]) <= {1, 2, 3, 4}
        cov = np.asarray(s["pose_cov"])
        np.testing.assert_allclose(cov, cov.T, atol=1e-12)
        assert set(info["rewards"]) == {"time", "collision", "pose_error", "discovery"}
        assert r == pytest.approx(sum(info["rewards"].values()))
        assert info["rewards"]["pose_error"] == pytest.approx(-0.1 * info["slam_error"]["position"])
        if trunc:
            break
    assert steps == 400
    assert info["slam_error"]["n_seen"] >= 1 and info["slam"]["n_landmarks"] >= 1


def test_render_draws_landmark_crosses():
    env = make(layout=DISC_ROOM, render_mode="rgb_array")
    env.reset(seed=0, options={"pose": [1.0, 2.0, -0.5]})  # facing the chair
    u = env.unwrapped
    assert u._estimate.count >= 1
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    state = u._render_state()
    state.pop("landmarks")
    without = u._renderer.draw(state)
    assert frame.shape == without.shape and not np.array_equal(frame, without)
    env.close()


# ---------------------------------------------------------------- landmark sensor
def test_landmark_sensor_range_and_bearing_in_a_hand_built_room():
    room = {
        "name": "one_chair",
        "outer": [[-1, -3], [6, -3], [6, 3], [-1, 3]],
        "objects": [{"class": "chair", "center": [3.0, 0.5], "size": [0.4, 0.4]}],
    }
    world = build_world(semreloc_env.get_layout(room))
    camera = SemanticCamera(CameraParams(**PERFECT_CAMERA))
    rng = np.random.default_rng(0)
    for theta in (0.0, 0.3):
        pose = np.array([0.0, 0.0, theta])
        scan = camera.read(world, pose, rng)
        surface = LandmarkSensor(camera, LandmarkSensorParams(point="middle", class_depth_m=(0, 0, 0, 0)))
        z, cls, ids = surface.read(world, pose, scan)
        assert z.shape == (1, 2) and cls.tolist() == [2] and ids.tolist() == [0]
        # the point lies on the chair's near face x = 2.8, 0.3 <= y <= 0.7
        x, y = z[0, 0] * np.cos(z[0, 1] + theta), z[0, 0] * np.sin(z[0, 1] + theta)
        assert x == pytest.approx(2.8, abs=1e-9) and 0.3 <= y <= 0.7
        beam = camera.angles[1] - camera.angles[0]
        assert z[0, 1] == pytest.approx(math.atan2(0.5, 2.8) - theta, abs=beam)
        assert z[0, 0] == pytest.approx(math.hypot(2.8, 0.5), abs=0.05)
        # the default class depth (chair 0.25 m) pushes the point along the same ray
        z2, _, _ = LandmarkSensor(camera, LandmarkSensorParams(point="middle")).read(world, pose, scan)
        assert z2[0, 0] == pytest.approx(z[0, 0] + 0.25) and z2[0, 1] == pytest.approx(z[0, 1])


def _scan(ranges, labels):
    ranges = np.asarray(ranges, dtype=float)
    return SemanticScan(ranges, np.linspace(-0.5, 0.5, ranges.size), np.asarray(labels), 4.5)


def test_extract_landmarks_splits_runs_and_flags_false_positives():
    ranges = [4.5, 2.0, 2.0, 2.0, 3.0, 3.0, 2.5, 2.5, 4.5, 1.0]
    labels = [0, 2, 2, 2, 2, 2, 3, 3, 0, 4]
    objects = [-1, 5, 5, 5, 6, 6, -1, -1, -1, 2]
    params = LandmarkSensorParams(class_depth_m=(0, 0, 0, 0), min_beams=2, skip_fov_edges=True)
    z, cls, ids = extract_landmarks(_scan(ranges, labels), params, np.asarray(objects))
    # chair run split by the 1 m range jump; trash-bin run on a wall (id -1); the cabinet beam at the edge dropped
    assert cls.tolist() == [2, 2, 3] and ids.tolist() == [5, 6, -1]
    ang = _scan(ranges, labels).angles
    mean_point = [r * np.mean(np.exp(1j * ang[a:b])) for r, (a, b) in [(2.0, (1, 4)), (3.0, (4, 6)), (2.5, (6, 8))]]
    np.testing.assert_allclose(z[:, 0], np.abs(mean_point), rtol=1e-12)  # range and bearing of the end points' mean
    np.testing.assert_allclose(z[:, 1], np.angle(mean_point), atol=1e-12)
    z, cls, ids = extract_landmarks(_scan(ranges, labels), LandmarkSensorParams(min_beams=1, skip_fov_edges=False))
    assert cls.tolist() == [2, 2, 3, 4] and ids.tolist() == [-1, -1, -1, -1]
    empty = extract_landmarks(_scan([4.5] * 4, [0] * 4))
    assert empty[0].shape == (0, 2) and empty[1].shape == (0,) and empty[2].shape == (0,)


def test_landmark_sensor_params_are_checked():
    for bad in ({"point": "centre"}, {"class_depth_m": (0.1, 0.2)}, {"min_beams": 0}, {"split_jump_m": -1.0}):
        with pytest.raises(ValueError, match="LandmarkSensorParams"):
            LandmarkSensorParams(**bad)
    with pytest.raises(ValueError, match="beam_objects"):
        extract_landmarks(_scan([2.0, 2.0], [1, 1]), None, np.zeros(3, dtype=int))


# ---------------------------------------------------------------- odometry motion model
def test_odometry_increment_model_mean_jacobians_and_covariance():
    model = OdometryIncrementModel(OdometryMotionConfig(alpha1=0.05, alpha2=0.02, alpha3=0.05, alpha4=0.01))
    assert isinstance(model, MotionModel)
    poses = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 2.5], [3.0, 1.0, -3.0]])
    u = np.array([0.3, 0.05, 0.2])
    np.testing.assert_allclose(model.mean(poses, u, 0.1), compose(poses, u), atol=1e-12)
    fx, fu = model.jacobians(poses, u, 0.1)
    eps = 1e-6
    for i in range(3):  # F_x against central differences
        d = np.zeros(3)
        d[i] = eps
        num = (model.mean(poses + d, u, 0.1) - model.mean(poses - d, u, 0.1)) / (2 * eps)
        np.testing.assert_allclose(fx[:, :, i], num, atol=1e-6)
    # F_u I F_u^T is the covariance of sample(): compare with 40000 draws from one pose
    rng = np.random.default_rng(0)
    draws = model.sample(np.tile(poses[1], (40000, 1)), u, 0.1, rng)
    pred = fu[1] @ model.control_cov @ fu[1].T
    np.testing.assert_allclose(np.cov(draws.T), pred, atol=0.05 * np.abs(pred).max())
    assert np.abs(pred).max() > 1e-4
    with pytest.raises(ValueError, match="odometry control"):
        model.mean(poses, [0.1, 0.0], 0.1)
    with pytest.raises(ValueError, match="odometry control"):
        model.jacobians(poses, [np.nan, 0.0, 0.0], 0.1)


def test_class_voting_fastslam_keeps_the_majority_class():
    slam = ClassVotingFastSLAM(
        OdometryIncrementModel(OdometryMotionConfig(0, 0, 0, 0)),
        RangeBearingNoise(0.05, 0.02),
        FastSLAMConfig(n_particles=5),
        np.random.default_rng(0),
        n_classes=4,
    )
    for label in (2, 2, 3, 2):  # one wrong class among four sightings of one landmark
        slam.predict(np.zeros(3), 0.1)
        slam.update([[2.0, 0.1]], None, [label])
    est = slam.estimate()
    assert est.count == 1 and slam.landmark_classes(est.landmark_ids).tolist() == [2]
    with pytest.raises(ValueError, match="class labels"):
        slam.update([[2.0, 0.1]], None, [7])
    with pytest.raises(ValueError, match="classes"):
        slam.update([[2.0, 0.1]], None, [1, 2])


# ---------------------------------------------------------------- SLAM accuracy
def _drive_disc_room(depth_m, steps=150):
    env = gym.make(
        "SemSlam-v2",
        layout=DISC_ROOM,
        odometry=NO_ODOM_NOISE,
        camera=PERFECT_CAMERA,
        slam={"n_particles": 10, "known_association": True},
        obs_noise={"sigma_r_m": 0.02, "sigma_b_rad": 0.01},
        landmark_sensor={"point": "middle", "class_depth_m": (depth_m,) * 4},
    )
    obs, info = env.reset(seed=0, options={"pose": [1.0, 2.0, 0.0]})
    policy = WallFollowExplorer()
    lm_errors, pos_errors = [], []
    for _ in range(steps):
        obs, _, _, _, info = env.step(policy(obs))
        if "landmark" in info["slam_error"]:  # left out until an object is seen
            lm_errors.append(info["slam_error"]["landmark"])
        pos_errors.append(info["slam_error"]["position"])
    return info, np.asarray(lm_errors), np.asarray(pos_errors)


def test_zero_noise_known_association_slam_keeps_landmark_error_near_zero():
    info, lm, pos = _drive_disc_room(DISC_R)
    assert info["slam_error"]["n_seen"] >= 3 and len(lm) > 100
    assert pos.max() < 1e-6  # exact odometry, matched noise-free motion model
    assert lm.max() < 0.06  # the middle beam misses the disc centre by under half a beam spacing
    assert sorted(info["slam"]["landmark_classes"]) == sorted(
        semreloc_env.get_layout(DISC_ROOM).objects[i].label for i in info["slam"]["landmark_ids"]
    )
    # control: without the depth prior the landmarks sit on the surface, one radius off the centres
    _, lm_surface, _ = _drive_disc_room(0.0)
    assert lm_surface[-1] == pytest.approx(DISC_R, abs=0.03)


# ---------------------------------------------------------------- bad input
def test_invalid_actions_raise_and_change_nothing():
    env = make()
    env.reset(seed=0)
    u = env.unwrapped
    env.step(0)
    pose, particles, lms = u.world.pose.copy(), u.slam.poses.copy(), u.slam.lm_mean.copy()
    for bad in (4, -1, 1.5, "forward", np.array([0, 1]), None):
        with pytest.raises(ValueError, match="invalid action"):
            env.step(bad)
    np.testing.assert_array_equal(u.world.pose, pose)
    np.testing.assert_array_equal(u.slam.poses, particles)
    np.testing.assert_array_equal(u.slam.lm_mean, lms)
    cont = make(action_type="continuous")
    cont.reset(seed=0)
    for bad in ([np.nan, 0.0], [2.0, 0.0], [0.5], "go"):
        with pytest.raises(ValueError, match="invalid action"):
            cont.step(bad)


def test_bad_reset_options_raise_and_keep_the_episode():
    env = make()
    env.reset(seed=0)
    env.step(0)
    u = env.unwrapped
    pose, slam = u.world.pose.copy(), u.slam
    for options, match in [
        ({"pose": [-5.0, 1.0, 0.0]}, "not free"),
        ({"pose": [np.nan, 1.0, 0.0]}, "finite"),
        ({"tracking": True}, "unknown reset options"),
    ]:
        with pytest.raises(ValueError, match=match):
            env.reset(options=options)
        np.testing.assert_array_equal(u.world.pose, pose)
        assert u.slam is slam
    env.step(0)  # the episode goes on


def test_unknown_or_bad_constructor_arguments_are_errors():
    with pytest.raises(TypeError):
        gym.make("SemSlam-v2", map_source="perfect")
    for kw, match in [
        ({"slam": {"particles": 10}}, "unknown keys"),
        ({"slam": {"woc_k": 0.5}}, "woc_k"),
        ({"slam": {"n_particles": 10**9}}, "n_particles"),
        ({"slam": {"version": 3}}, "version"),
        ({"slam": {"n_particles": 0}}, "n_particles"),
        ({"slam": {"known_association": "yes"}}, "known_association"),
        ({"slam": {"motion_noise": {"alpha9": 1.0}}}, "unknown keys"),
        ({"obs_noise": {"sigma_r_m": -0.1}}, "observation noise"),
        ({"obs_noise": {"range": 0.1}}, "unknown keys"),
        ({"landmark_sensor": {"point": "centre"}}, "point"),
        ({"reward_weights": {"bonus": 1.0}}, "unknown keys"),
        ({"action_type": "joystick"}, "action_type"),
    ]:
        with pytest.raises(ValueError, match=match):
            make(**kw)


def test_step_before_reset_is_an_error():
    with pytest.raises(RuntimeError, match="reset"):
        make().unwrapped.step(0)


def test_slam_beats_dead_reckoning_when_it_keeps_seeing_the_same_objects():
    """Noisy odometry (alphas 0.1); the robot looks around one room, so landmarks bound the drift."""
    slam_err, dr_err, lm_err = [], [], []
    for seed in range(3):
        noisy = {"alpha1": 0.1, "alpha2": 0.1, "alpha3": 0.1, "alpha4": 0.05}
        env = make(layout="twin_rooms", odometry=noisy, slam={"n_particles": 100})
        obs, info = env.reset(seed=seed, options={"pose": [2.5, 3.0, 0.0]})
        dr = info["pose"].copy()
        for t in range(300):  # 60 steps turning left, then 10 forward + 50 turning right, and so on
            obs, _, _, _, info = env.step(1 if (t // 60) % 2 == 0 else (0 if t % 60 < 10 else 2))
            dr = compose(dr, obs["odometry"].astype(np.float64))
        slam_err.append([info["slam_error"]["position"], info["slam_error"]["heading"]])
        dr_err.append([np.hypot(*(dr[:2] - info["pose"][:2])), abs(float(wrap_angle(dr[2] - info["pose"][2])))])
        lm_err.append(info["slam_error"]["landmark"])
    slam_err, dr_err = np.mean(slam_err, axis=0), np.mean(dr_err, axis=0)
    assert slam_err[0] < dr_err[0] and slam_err[1] < 0.5 * dr_err[1], (slam_err, dr_err)
    assert np.mean(lm_err) < 0.5


def test_semslam_eval_gives_the_same_table_on_both_ids(capsys):
    """``--env-id`` picks the env; v0 and v1 differ only in observation layout and info keys, so the tables
    (a short run in which one episode sees no object) are the same."""
    from agents.experiments import semslam_eval

    tables = {}
    for env_id in ("SemSlam-v0", "SemSlam-v1"):
        assert semslam_eval.main(["--env-id", env_id, "--seeds", "2", "--steps", "30", "--layout", "twin_rooms"]) == 0
        tables[env_id] = capsys.readouterr().out.split("| variant", 1)[1]
    assert tables["SemSlam-v0"] == tables["SemSlam-v1"]
    assert "WOCPF (K=2), ML association" in tables["SemSlam-v1"]
    assert "undefined in 1 episode(s)" in tables["SemSlam-v1"]  # v1's info has no landmark error there


def test_the_slam_odometry_model_takes_exact_small_moves_too():
    """An outside SLAM audit: the SLAM motion model also took a step under min_trans_m along the heading (SemSlam-v1
    with continuous actions at -0.15 moved its estimate forwards while the robot backed). exact_small_moves, off by
    default so that every env's episodes stay as they were, moves it in its own direction, its Jacobian too."""
    from filters.motion.odometry import OdometryMotionConfig
    from filters.motion.odometry_slam import OdometryIncrementModel

    exact = OdometryIncrementModel(OdometryMotionConfig(exact_small_moves=True))
    start = np.array([[1.0, 2.0, 0.4]])
    for delta in ([-0.005, 0.0, 0.0], [0.0, 0.008, 0.1]):
        np.testing.assert_allclose(exact.mean(start, delta)[0], compose(start[0], np.array(delta)), atol=1e-12)
        fx, _ = exact.jacobians(start, delta)
        eps = 1e-7
        bumped = start + np.array([[0.0, 0.0, eps]])
        numeric = (exact.mean(bumped, delta)[0] - exact.mean(start, delta)[0]) / eps
        np.testing.assert_allclose(fx[0][:, 2], numeric, atol=1e-6)
    legacy = OdometryIncrementModel()
    assert legacy.mean(start, [-0.005, 0.0, 0.0])[0][0] > start[0, 0]  # the default: forwards, as before
