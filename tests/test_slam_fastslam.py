import math

import numpy as np
import pytest

from filters.motion.velocity import BicycleModel, UnicycleModel
from filters.simulators.car_sim import CarSimConfig, run_slam, simulate, small_course
from filters.slam.association import AssociationConfig
from filters.slam.fastslam import FastSLAM, FastSLAMConfig
from filters.slam.landmarks import RangeBearingNoise
from filters.slam.weight_transforms import WOC, get_weight_transform, identity, woc

TINY_NOISE = RangeBearingNoise(1e-4, 1e-5)


def _drive(filt, run, every_scan=None):
    run_slam(filt, run, every_scan)
    return filt.estimate()


@pytest.fixture(scope="module")
def clean_run():
    cfg = CarSimConfig(n_loops=1, control_noise=False, sensor_noise=False)
    return simulate(cfg, small_course(), np.random.default_rng(0))


@pytest.fixture(scope="module")
def noisy_run():
    cfg = CarSimConfig(max_steps=500)
    return simulate(cfg, small_course(), np.random.default_rng(3))


@pytest.mark.parametrize("version", [1, 2])
@pytest.mark.parametrize("mode", ["known", "ml"])
def test_zero_noise_recovers_landmarks_exactly(clean_run, version, mode):
    motion = BicycleModel(4.0, 1e-6, 1e-7)
    cfg = FastSLAMConfig(n_particles=10, version=version, association=AssociationConfig(mode))
    f = FastSLAM(motion, TINY_NOISE, cfg, np.random.default_rng(1))
    est = _drive(f, clean_run)
    assert est.count == clean_run.landmarks.shape[0]
    if mode == "known":
        truth = clean_run.landmarks[est.landmark_ids]
    else:
        d = np.linalg.norm(est.landmarks[:, None] - clean_run.landmarks[None], axis=-1)
        assert sorted(d.argmin(axis=1)) == list(range(clean_run.landmarks.shape[0]))  # one estimate per landmark
        truth = clean_run.landmarks[d.argmin(axis=1)]
    np.testing.assert_allclose(est.landmarks, truth, atol=1e-3)
    np.testing.assert_allclose(est.pose[:2], clean_run.true_poses[-1, :2], atol=1e-3)


def test_woc_transform_limits():
    w = np.array([0.7, 0.2, 0.1, 0.0])
    np.testing.assert_allclose(woc(w, 1.0), np.full(4, 0.25))
    np.testing.assert_array_equal(woc(w, math.inf), identity(w))  # plain (normalised) weights
    np.testing.assert_allclose(woc(w, 1e12), w, atol=1e-11)
    np.testing.assert_allclose(woc(w, 2.0), 0.5 * w + 0.125)
    np.testing.assert_allclose(woc(w * 3.0, 4.0).sum(), 1.0)  # normalised output
    np.testing.assert_allclose(identity(w * 5.0), w)
    assert get_weight_transform("woc", K=3.0)(w)[3] > 0.0
    for bad in (0.5, 0.0, -1.0, math.nan):
        with pytest.raises(ValueError):
            woc(w, bad)
    with pytest.raises(ValueError):
        WOC(0.9)


def _filter_with_three_landmarks(version=1):
    cfg = FastSLAMConfig(n_particles=8, version=version, association=AssociationConfig("ml"))
    f = FastSLAM(UnicycleModel(0.01, 0.001), RangeBearingNoise(0.1, math.radians(1.0)), cfg, np.random.default_rng(0))
    lms = np.array([[10.0, 0.0], [10.0, 8.0], [12.0, -9.0]])
    z = np.stack([np.hypot(lms[:, 0], lms[:, 1]), np.arctan2(lms[:, 1], lms[:, 0])], axis=1)
    f.update(z)
    return f, lms, z


@pytest.mark.parametrize("version", [1, 2])
def test_ml_association_picks_the_right_landmark(version):
    f, lms, z = _filter_with_three_landmarks(version)
    assert np.all(f.count == 3)
    z_new = np.array([[math.hypot(10.0, 8.0) + 0.05, math.atan2(8.0, 10.0) - 0.005], [20.0, 2.5]])
    assoc = f._associate(z_new, None)
    assert np.all(assoc.matched[:, 0]) and np.all(assoc.slots[:, 0] == 1)  # landmark created second
    assert np.all(assoc.new[:, 1]) and np.all(assoc.slots[:, 1] == 3)  # far from every landmark: new slot
    f.update(z_new)
    assert np.all(f.count == 4)


def test_no_observation_stretch_stays_finite():
    for version in (1, 2):
        f, _, _ = _filter_with_three_landmarks(version)
        for _ in range(3000):
            f.predict([1.0, 0.05], 0.025)
            f.update(None)
            f.update(np.zeros((0, 2)))
        est = f.estimate()
        assert np.all(np.isfinite(est.pose)) and np.all(np.isfinite(est.pose_cov))
        assert np.all(np.isfinite(f.log_weights)) and np.all(np.isfinite(f.lm_mean))
        assert est.pose_cov[0, 0] > 0.0  # uncertainty grew
        assert f.n_updates == 1  # empty scans are predict-only steps


def test_bad_inputs_raise():
    f, _, _ = _filter_with_three_landmarks()
    for bad in ([[math.nan, 0.1]], [[-1.0, 0.1]], [[5.0, 4.0]], [[5.0, 0.1, 0.0]], [[math.inf, 0.0]]):
        with pytest.raises(ValueError):
            f.update(np.array(bad))
    with pytest.raises(ValueError):
        FastSLAMConfig(n_particles=0)
    with pytest.raises(ValueError):
        FastSLAMConfig(weight_transform=WOC(0.5))
    with pytest.raises(ValueError):
        FastSLAMConfig(resampler="nope")
    with pytest.raises(TypeError, match="weight_transform must be a callable"):
        FastSLAMConfig(weight_transform=5)  # an outside tester's: the first update failed after changing the state
    with pytest.raises(ValueError, match=r"gate_new < inf"):
        AssociationConfig(gate_new=math.inf)  # no landmark would be made once one exists
    before = (f.poses.copy(), f.lm_mean.copy(), f.lm_cov.copy())
    with pytest.raises(ValueError, match="at most 1e\\+06 m"):
        f.update(np.array([[1e200, 0.1]]))  # finite, but its square overflowed the covariances to inf
    np.testing.assert_array_equal(before[0], f.poses)
    np.testing.assert_array_equal(before[1], f.lm_mean)
    np.testing.assert_array_equal(before[2], f.lm_cov)
    known = FastSLAM(
        UnicycleModel(), TINY_NOISE, FastSLAMConfig(association=AssociationConfig("known")), np.random.default_rng(0)
    )
    with pytest.raises(ValueError):
        known.update([[5.0, 0.1]])  # known association without ids
    with pytest.raises(ValueError):
        known.update([[5.0, 0.1]], ids=[-1])
    with pytest.raises(ValueError):
        known.predict([1.0, math.nan], 0.1)


@pytest.mark.parametrize("version", [1, 2])
def test_same_seed_bit_identical(noisy_run, version):
    def once(seed):
        motion = BicycleModel(4.0, 0.3, math.radians(3.0))
        cfg = FastSLAMConfig(n_particles=15, version=version, weight_transform=WOC(3.0))
        f = FastSLAM(motion, RangeBearingNoise(0.1, math.radians(1.0)), cfg, np.random.default_rng(seed))
        _drive(f, noisy_run)
        return f

    a, b, c = once(5), once(5), once(6)
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.lm_mean, b.lm_mean)
    np.testing.assert_array_equal(a.last_weights, b.last_weights)
    assert not np.array_equal(a.poses, c.poses)


def test_circular_mean_of_heading():
    cfg = FastSLAMConfig(n_particles=2, version=1)
    f = FastSLAM(UnicycleModel(), TINY_NOISE, cfg, np.random.default_rng(0))
    f.poses = np.array([[0.0, 0.0, math.pi - 0.1], [2.0, 0.0, -math.pi + 0.1]])
    est = f.estimate()
    assert abs(abs(est.pose[2]) - math.pi) < 1e-9
    np.testing.assert_allclose(est.pose[:2], [1.0, 0.0])
    np.testing.assert_allclose(est.pose_cov[2, 2], 0.01, rtol=1e-9)


def test_hooks_are_called_in_order_and_resampling_mask_mutates():
    calls = []

    class Probe(FastSLAM):
        def _move_particles(self, z, assoc):
            calls.append("move")
            self.poses[:, 1] += 100.0  # far off: a new landmark is created relative to the moved pose

        def _transform_weights(self, weights):
            calls.append("transform")
            return super()._transform_weights(weights)

        def _resample(self, psi):
            calls.append("resample")
            n = self.n_particles
            return np.zeros(n, dtype=np.int64), np.arange(n) >= n // 2

        def _mutate(self, mask):
            calls.append(("mutate", int(mask.sum())))
            self.poses[mask, 0] += 1.0

    f = Probe(UnicycleModel(), TINY_NOISE, FastSLAMConfig(n_particles=6, version=1), np.random.default_rng(0))
    f.update([[10.0, 0.0]])
    assert calls == ["move", "transform", "resample", ("mutate", 3)]
    np.testing.assert_allclose(f.lm_mean[:, 0], [[10.0, 100.0]] * 6, atol=1e-9)  # map used the moved pose
    np.testing.assert_allclose(f.poses[:, 0], [0, 0, 0, 1, 1, 1])
    np.testing.assert_allclose(f.weights, np.full(6, 1 / 6))


def test_resampling_threshold_skips_when_weights_even():
    cfg = FastSLAMConfig(n_particles=5, version=1, resample_ess_fraction=0.5, association=AssociationConfig("known"))
    f = FastSLAM(UnicycleModel(), TINY_NOISE, cfg, np.random.default_rng(0))
    f.update([[10.0, 0.0]], ids=[0])  # all particles identical: equal weights, ESS = N
    assert f.n_resamples == 0 and f.n_updates == 1
    f.poses[0, 1] += 1.0  # particle 0 now disagrees strongly with the next scan
    f.update([[10.0, 0.0]], ids=[0])
    assert f.n_resamples == 0  # 4 of 5 particles keep equal weight: ESS ~ 4 > 2.5
    assert f.last_weights[0] < 1e-6


def test_constructor_and_id_checks():
    # a new user's trial: a NaN initial covariance, rng=None and n_particles=True were taken and failed later
    with pytest.raises(ValueError, match="initial_pose_cov must be finite"):
        FastSLAM(
            UnicycleModel(),
            TINY_NOISE,
            FastSLAMConfig(),
            np.random.default_rng(0),
            initial_pose_cov=np.full((3, 3), np.nan),
        )
    with pytest.raises(ValueError, match="positive semi-definite"):
        FastSLAM(UnicycleModel(), TINY_NOISE, FastSLAMConfig(), np.random.default_rng(0), initial_pose_cov=-np.eye(3))
    with pytest.raises(TypeError, match="rng must be a numpy.random.Generator"):
        FastSLAM(UnicycleModel(), TINY_NOISE, FastSLAMConfig(), None)
    with pytest.raises(ValueError, match="n_particles must be a positive integer"):
        FastSLAMConfig(n_particles=True)
    known = FastSLAM(
        UnicycleModel(), TINY_NOISE, FastSLAMConfig(association=AssociationConfig("known")), np.random.default_rng(0)
    )
    with pytest.raises(ValueError, match="at most 100,000"):
        known.update(np.array([[1.0, 0.0]]), ids=[10**9])
    assert known.n_updates == 0  # the refused scan changed nothing
    ml = FastSLAM(UnicycleModel(), TINY_NOISE, FastSLAMConfig(), np.random.default_rng(0))
    ml.update(np.array([[1.0, 0.0]]), ids=[10**9])  # maximum-likelihood association ignores the ids


@pytest.mark.parametrize("kind", ["fastslam1", "fastslam2", "ekf"])
def test_predict_refuses_what_would_make_the_state_non_finite_and_changes_nothing(kind):
    # a new user's trial: dt = inf turned the pose into [inf, nan, nan] with only RuntimeWarnings
    from filters.slam.ekf_slam import EKFSLAM

    noise = RangeBearingNoise(0.1, 0.02)
    if kind == "ekf":
        f = EKFSLAM(UnicycleModel(), noise)
    else:
        f = FastSLAM(UnicycleModel(), noise, FastSLAMConfig(20, version=int(kind[-1])), np.random.default_rng(0))
    f.predict([1.0, 0.1], 0.1)
    state = (f.x.copy(), f.P.copy()) if kind == "ekf" else (f.poses.copy(), f.pose_cov.copy())
    for u, dt, match in [
        ([1.0, 0.0], math.inf, "dt must be a finite number > 0"),
        ([1.0, 0.0], True, "dt must be a finite number > 0"),
        ([1.0, 0.0], 0.0, "dt must be a finite number > 0"),
        ([1.0, math.nan], 0.1, "control u must be a 1-D array of finite numbers"),
        ("fast", 0.1, "control u must be"),
        ([1e308, 0.0], 1e10, "moves the pose"),
    ]:
        with pytest.raises(ValueError, match=match):
            f.predict(u, dt)
    after = (f.x, f.P) if kind == "ekf" else (f.poses, f.pose_cov)
    for a, b in zip(state, after):
        np.testing.assert_array_equal(a, b)


def test_model_and_config_numbers_are_checked():
    for bad in [dict(sigma_v_mps=math.inf), dict(sigma_w_radps=math.nan), dict(sigma_v_mps="0.1")]:
        with pytest.raises(ValueError, match="invalid unicycle model parameters"):
            UnicycleModel(**bad)
    with pytest.raises(ValueError, match="invalid bicycle model parameters"):
        BicycleModel(wheelbase_m=math.inf)
    with pytest.raises(ValueError, match="version must be 1 or 2, got True"):
        FastSLAMConfig(version=True)
    with pytest.raises(ValueError, match="initial_capacity must be an integer >= 1, got 2.5"):
        FastSLAMConfig(initial_capacity=2.5)


def test_a_new_landmark_seen_twice_in_one_scan_does_not_refine_the_pose():
    # a twenty-third tester's: under known association the second sighting of a new id refined the pose
    # against the empty slot (a landmark at the origin with no covariance), collapsing the heading spread
    from filters.motion.velocity import UnicycleModel
    from filters.slam.association import AssociationConfig
    from filters.slam.fastslam import FastSLAM, FastSLAMConfig
    from filters.slam.landmarks import RangeBearingNoise

    spreads = []
    for ids in ([5], [5, 5]):
        f = FastSLAM(
            UnicycleModel(),
            RangeBearingNoise(0.1, 0.01),
            FastSLAMConfig(n_particles=200, version=2, association=AssociationConfig(mode="known")),
            np.random.default_rng(0),
            initial_pose_cov=np.diag([0.5, 0.5, 0.1]),
        )
        f.update(np.array([[10.0, 0.0]] * len(ids)), np.array(ids))
        spreads.append(f.poses[:, 2].std())
        assert np.all(f.count == 1)
    assert spreads[1] == pytest.approx(spreads[0]) and spreads[0] > 0.25  # the prior's sqrt(0.1)
