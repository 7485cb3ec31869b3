import math

import numpy as np
import pytest

from filters.motion.velocity import BicycleModel, UnicycleModel
from filters.simulators.car_sim import CarSimConfig, run_slam, simulate, small_course
from filters.slam.association import AssociationConfig
from filters.slam.ekf_slam import EKFSLAM, EKFSLAMConfig
from filters.slam.landmarks import (
    RangeBearingNoise,
    inverse_observation,
    observation_jacobians,
    predict_observation,
    validate_observations,
)

NOISE = RangeBearingNoise(0.1, math.radians(1.0))


def _drive(filt, run):
    run_slam(filt, run)
    return filt.estimate()


# ------------------------------------------------------------------ observation model
def test_observation_prediction_vectorised_and_wrapped():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, math.pi / 2]])
    lms = np.array([[[3.0, 4.0], [-1.0, 0.0]], [[1.0, 3.0], [0.0, 1.0]]])
    z = predict_observation(poses[:, None, :], lms)
    assert z.shape == (2, 2, 2)
    np.testing.assert_allclose(z[0, 0], [5.0, math.atan2(4, 3)])
    np.testing.assert_allclose(z[0, 1], [1.0, -math.pi])  # pi wraps to -pi
    np.testing.assert_allclose(z[1, 0], [2.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(z[1, 1], [1.0, math.pi / 2])
    assert np.all(z[..., 1] >= -math.pi) and np.all(z[..., 1] < math.pi)


def test_jacobians_match_finite_differences():
    pose = np.array([1.0, -2.0, 0.4])
    lm = np.array([6.0, 1.5])
    _, h_x, h_l = observation_jacobians(pose, lm)
    eps = 1e-6
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        num = (predict_observation(pose + d, lm) - predict_observation(pose - d, lm)) / (2 * eps)
        np.testing.assert_allclose(h_x[:, i], num, atol=1e-6)
    for i in range(2):
        d = np.zeros(2)
        d[i] = eps
        num = (predict_observation(pose, lm + d) - predict_observation(pose, lm - d)) / (2 * eps)
        np.testing.assert_allclose(h_l[:, i], num, atol=1e-6)


def test_inverse_observation_round_trip_and_jacobian():
    pose = np.array([2.0, 1.0, -2.5])
    z = np.array([7.0, 1.2])
    lm, g_x, g_z = inverse_observation(pose, z)
    np.testing.assert_allclose(predict_observation(pose, lm), z, atol=1e-12)
    eps = 1e-6
    for i in range(2):
        d = np.zeros(2)
        d[i] = eps
        num = (inverse_observation(pose, z + d)[0] - inverse_observation(pose, z - d)[0]) / (2 * eps)
        np.testing.assert_allclose(g_z[:, i], num, atol=1e-6)
    d = np.array([0.0, 0.0, eps])
    num = (inverse_observation(pose + d, z)[0] - inverse_observation(pose - d, z)[0]) / (2 * eps)
    np.testing.assert_allclose(g_x[:, 2], num, atol=1e-6)


def test_validate_observations():
    z, ids = validate_observations([[1.0, math.pi]], [3])
    np.testing.assert_allclose(z, [[1.0, -math.pi]])
    assert ids.dtype == np.int64
    assert validate_observations(None)[0].shape == (0, 2)
    with pytest.raises(ValueError, match="NaN"):
        validate_observations([[math.nan, 0.0]])
    with pytest.raises(ValueError, match="range"):
        validate_observations([[-0.1, 0.0]])
    with pytest.raises(ValueError, match="bearing"):
        validate_observations([[1.0, -3.2]])
    with pytest.raises(ValueError):
        validate_observations([[1.0, 0.0]], [1, 2])
    with pytest.raises(ValueError):
        validate_observations([[1.0, 0.0]], [0.5])


@pytest.mark.parametrize("model", [BicycleModel(4.0, 0.1, 0.01), UnicycleModel(0.1, 0.01)])
def test_motion_jacobians_match_finite_differences(model):
    poses = np.array([[1.0, 2.0, 0.3], [-1.0, 0.5, -2.9]])
    u, dt, eps = np.array([3.0, 0.2]), 0.1, 1e-6
    fx, fu = model.jacobians(poses, u, dt)
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        num = (model.mean(poses + d, u, dt) - model.mean(poses - d, u, dt)) / (2 * eps)
        np.testing.assert_allclose(fx[:, :, i], num, atol=1e-6)
    for i in range(2):
        d = np.zeros(2)
        d[i] = eps
        num = (model.mean(poses, u + d, dt) - model.mean(poses, u - d, dt)) / (2 * eps)
        np.testing.assert_allclose(fu[:, :, i], num, atol=1e-6)
    s = model.sample(np.zeros((4000, 3)), u, dt, np.random.default_rng(0))
    assert s.shape == (4000, 3) and np.std(s[:, 0]) > 0


# ------------------------------------------------------------------ EKF-SLAM
@pytest.fixture(scope="module")
def clean_run():
    cfg = CarSimConfig(n_loops=1, control_noise=False, sensor_noise=False)
    return simulate(cfg, small_course(), np.random.default_rng(0))


@pytest.mark.parametrize("mode", ["known", "ml"])
def test_zero_noise_recovers_landmarks_exactly(clean_run, mode):
    f = EKFSLAM(BicycleModel(4.0, 1e-6, 1e-7), RangeBearingNoise(1e-4, 1e-5), EKFSLAMConfig(AssociationConfig(mode)))
    est = _drive(f, clean_run)
    assert est.count == clean_run.landmarks.shape[0]
    if mode == "known":
        truth = clean_run.landmarks[est.landmark_ids]
    else:
        d = np.linalg.norm(est.landmarks[:, None] - clean_run.landmarks[None], axis=-1)
        assert sorted(d.argmin(axis=1)) == list(range(clean_run.landmarks.shape[0]))
        truth = clean_run.landmarks[d.argmin(axis=1)]
    np.testing.assert_allclose(est.landmarks, truth, atol=1e-6)
    np.testing.assert_allclose(est.pose[:2], clean_run.true_poses[-1, :2], atol=1e-6)


def test_ml_association_picks_the_right_landmark():
    f = EKFSLAM(UnicycleModel(0.01, 0.001), NOISE)
    lms = np.array([[10.0, 0.0], [10.0, 8.0], [12.0, -9.0]])
    f.update(np.stack([np.hypot(lms[:, 0], lms[:, 1]), np.arctan2(lms[:, 1], lms[:, 0])], axis=1))
    assert f.n_landmarks == 3
    assert f._associate_ml(np.array([math.hypot(10, 8) + 0.05, math.atan2(8, 10) - 0.005])) == (1, False)
    assert f._associate_ml(np.array([20.0, 2.5])) == (None, True)
    before = f.estimate().landmark_covs[1].copy()
    f.update([[math.hypot(10, 8), math.atan2(8, 10)]])
    assert f.n_landmarks == 3
    assert np.trace(f.estimate().landmark_covs[1]) < np.trace(before)  # the matched landmark was refined


def test_no_observation_stretch_stays_finite_and_grows_uncertainty():
    f = EKFSLAM(BicycleModel(4.0, 0.3, math.radians(3.0)), NOISE)
    f.update([[10.0, 0.2], [15.0, -0.3]])
    p0 = f.P[0, 0]
    for _ in range(5000):
        f.predict([3.0, 0.05], 0.025)
        f.update(None)
    assert np.all(np.isfinite(f.x)) and np.all(np.isfinite(f.P))
    assert f.P[0, 0] > p0
    assert np.allclose(f.P, f.P.T)


def test_bad_inputs_raise():
    f = EKFSLAM(UnicycleModel(), NOISE, EKFSLAMConfig(AssociationConfig("known")))
    for bad in ([[math.nan, 0.1]], [[-1.0, 0.1]], [[5.0, -4.0]], [[1e200, 0.1]]):
        with pytest.raises(ValueError):
            f.update(bad, ids=[0])
    with pytest.raises(ValueError):
        f.update([[5.0, 0.1]])  # known association without ids
    with pytest.raises(ValueError):
        f.predict([1.0, 0.0], 0.0)
    with pytest.raises(ValueError):
        AssociationConfig("nearest")
    assert f.n_landmarks == 0  # nothing half-applied


def test_deterministic_on_same_data():
    run = simulate(CarSimConfig(max_steps=800), small_course(), np.random.default_rng(4))
    a = _drive(EKFSLAM(BicycleModel(4.0, 0.3, math.radians(3.0)), NOISE), run)
    b = _drive(EKFSLAM(BicycleModel(4.0, 0.3, math.radians(3.0)), NOISE), run)
    np.testing.assert_array_equal(a.pose, b.pose)
    np.testing.assert_array_equal(a.landmarks, b.landmarks)
    assert np.linalg.norm(a.pose[:2] - run.true_poses[-1, :2]) < 2.0


def test_initial_pose_cov_is_checked():
    # a new user's trial: a NaN initial covariance built a wrong map without a word
    with pytest.raises(ValueError, match="initial_pose_cov must be finite"):
        EKFSLAM(UnicycleModel(), RangeBearingNoise(0.1, 0.01), initial_pose_cov=np.full((3, 3), np.nan))
    ekf = EKFSLAM(UnicycleModel(), RangeBearingNoise(0.1, 0.01), EKFSLAMConfig(association=AssociationConfig("known")))
    ekf.update(np.array([[1.0, 0.0]]), ids=[123_456])  # EKF-SLAM keeps ids in a dict: any id is fine
    assert ekf.ids.tolist() == [123_456]
    with pytest.raises(ValueError, match="must be symmetric"):
        EKFSLAM(UnicycleModel(), RangeBearingNoise(0.1, 0.01), initial_pose_cov=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]])


@pytest.mark.parametrize("gate_first, expected", [(False, (None, False)), (True, (1, False))])
def test_ml_association_can_choose_among_the_landmarks_inside_the_gate(gate_first, expected):
    """An outside SLAM audit: the candidate of least NIS + log det S was chosen over all landmarks and then gated, so
    a tight landmark outside the gate (A) beat one inside it (B) and the observation was ignored. The default keeps
    that, so that every run stays as it was; gate_first chooses among the landmarks inside the gate."""
    f = EKFSLAM(BicycleModel(4.0, 1e-6, 1e-7), RangeBearingNoise(0.01, 0.001),
                EKFSLAMConfig(AssociationConfig("ml", gate_first=gate_first)))  # fmt: skip
    f.x = np.array([0.0, 0.0, 0.0, 10.0, 0.0, 10.0, 0.6])
    f.P = np.diag([0.0, 0.0, 0.0, 1e-6, 1e-6, 0.09, 0.09])
    assert f._associate_ml(np.array([10.04, 0.0])) == expected
    with pytest.raises(ValueError, match="gate_first must be a bool"):
        AssociationConfig(gate_first=1)
